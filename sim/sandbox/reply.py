"""The host's reader of a guest's reply: data only, whatever the untrusted code wrote.

The guest may be the untrusted code itself (it can write to the reply pipe, or replace the
guest's own functions), so nothing of a reply is trusted: it is read by this reader alone, never
by `wire.decode`, and it accepts nothing but

    {"ok": VALUE, "confined": bool}       a value (`confined` only in the first reply)
    {"error": ERROR, "confined": bool}    the untrusted code raised
    VALUE := null | true | false | number | string | [VALUE, ...] | {"__type__": string}
    ERROR := {"type": str, "message": str, "line": int|null, "missing": str|null,
              "index": int|null, "value_error": bool}

No other object, key or tag: a reply cannot name a Python attribute (a record's `__class__`,
an `__array_interface__` numpy would follow into memory), and a numpy array arrives as nested
lists that `np.asarray(..., dtype=float64)` copies as numbers. Lists nest at most `DEPTH` deep,
strings are cut (`STRING`), so a malformed reply of any size or depth is a `WireError` (the
student's protocol error), never the host's crash.
"""

from __future__ import annotations

import json
from typing import Any

from sim.sandbox.wire import Opaque, WireError

DEPTH = 32
"""Deepest nesting of lists a reply may hold (a pose list of lists is 2 deep)."""
STRING = 1000
"""Characters kept of a string in a reply (type names, messages; the rest is cut)."""
ERROR_FIELDS = {"type": str, "message": str, "line": (int, type(None)), "missing": (str, type(None)), "index": (int, type(None)),
                "value_error": bool}  # fmt: skip
"""The fixed fields of an error and their types."""


def read(body: bytes) -> dict[str, Any]:
    """A reply's body as {"ok": value} or {"error": fields} (plus "confined" when sent); a
    WireError naming what is wrong for anything else."""
    try:
        message = json.loads(body.decode("utf-8"))
    except (ValueError, RecursionError) as err:  # UnicodeDecodeError, JSONDecodeError, too many digits
        raise WireError(f"not JSON ({type(err).__name__})") from None
    if not isinstance(message, dict) or len(message.keys() & {"ok", "error"}) != 1 or not message.keys() <= {"ok", "error", "confined"}:
        raise WireError("not a reply of the sandbox (its fields are ok or error, and confined)")
    reply: dict[str, Any] = {}
    if "confined" in message:
        if not isinstance(message["confined"], bool):
            raise WireError("a reply whose 'confined' is not true or false")
        reply["confined"] = message["confined"]
    if "ok" in message:
        reply["ok"] = value(message["ok"])
    else:
        reply["error"] = error(message["error"])
    return reply


def value(data: Any, depth: int = 0) -> Any:
    """A reply's value as plain Python (lists, numbers, strings, None, `Opaque`), checked."""
    if data is None or isinstance(data, (bool, int, float)):
        return data
    if isinstance(data, str):
        return data[:STRING]
    if isinstance(data, list):
        if depth >= DEPTH:
            raise WireError(f"a value nested more than {DEPTH} lists deep")
        return [value(item, depth + 1) for item in data]
    if isinstance(data, dict) and data.keys() == {"__type__"} and isinstance(data["__type__"], str):
        return Opaque(data["__type__"][:100])
    raise WireError("a value that is not numbers, strings or lists (an object with other fields)")


def error(data: Any) -> dict[str, Any]:
    """An error's fixed fields, each of its type (a bool is no line number), strings cut."""
    if not (isinstance(data, dict) and data.keys() == ERROR_FIELDS.keys()):
        raise WireError(f"an error whose fields are not {', '.join(ERROR_FIELDS)}")
    for key, kind in ERROR_FIELDS.items():
        field = data[key]
        if not isinstance(field, kind) or (kind is not bool and isinstance(field, bool)):
            raise WireError(f"an error whose '{key}' is a {type(field).__name__}")
    return {key: field[:STRING] if isinstance(field, str) else field for key, field in data.items()}
