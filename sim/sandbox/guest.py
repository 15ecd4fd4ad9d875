"""The program inside the sandbox: it confines itself, loads the untrusted file and answers requests.

Started as `python -I -S -B -c "import sys; sys.path[:0] = PATH; import guest; guest.main()"
CONFIG` (imported, not run as a script, so that its compiled form is used; CONFIG: JSON with
`path`, the folders to import from; `code`, the file; `preload`, the modules imported before the
file's folder is on the path (numpy, the project modules it may use); `limits`; `requests` and `replies`, the
file descriptors of its two pipes, both in the `wire` format). It first sets its limits and the
filter against new processes and threads (`confine`), then loads the file as the module
`ctsim_student` and says {"ok": null} or {"error": ...}; then, per request:

    {"op": "call", "name": f, "args": [...]}                          -> f(*args)
    {"op": "new", "handle": h, "name": C, "kwargs": {...}}             -> objects[h] = C(**kwargs)
    {"op": "method", "handle": h, "name": m, "args": [...], "attribute": a or [a, b] or null}
                                                                       -> objects[h].m(*args), or
                                                                          objects[h].a after it
                                                                          (a list: each, None where
                                                                          it has none)
    {"op": "step", "handle": h, "t": t, "readings": R}                 -> objects[h].step(t, R) as a
                                                                          command list (below)
    {"op": "feed", "handle": h, "name": m, "series": [[args], ...], "attribute": a}
                                                                       -> objects[h].a after each
                                                                          objects[h].m(*args), a list
                                                                          (a whole run in one request)

A reply is {"ok": value} with the value as plain data (lists, numbers, strings; tuples and
numeric numpy arrays as lists; an object of another kind becomes {"__type__": its type name}; a
command [type name, numbers...] or ["bad", type name]), or
{"error": {"type", "message", "line", "missing", "index", "value_error"}} (`index`: the call of a
feed that raised, else null; `value_error`: the exception is a ValueError, input refused). It
never sees what the host compares with.
"""

from __future__ import annotations

import builtins
import importlib.util
import json
import sys
import traceback
from pathlib import Path
from typing import Any

STUDENT_MODULE = "ctsim_student"
REQUEST_LIMIT = 1 << 24
"""Bytes of one request (the host's; a run's readings are a few hundred)."""
COMMANDS = {"WheelSpeeds": ("left", "right"), "Twist": ("v", "omega", "vy"), "CurveCommand": ("kappa_n", "beta", "v_n")}
"""The command types of `bots.commands` and their fields, in the order a command list holds them."""


class FeedError(Exception):
    """The call `index` of a feed raised (the untrusted code's exception is its cause)."""

    def __init__(self, index: int):
        super().__init__(index)
        self.index = index


def describe(err: BaseException, path: str) -> dict[str, Any]:
    """What went wrong, as plain data: exception type, first line of its message, the line of the
    untrusted file it came from, the module it could not find (an import of the project), and
    which call of a feed it was."""
    index = err.index if isinstance(err, FeedError) else None
    err = err.__cause__ if isinstance(err, FeedError) else err
    line = None
    for frame in traceback.extract_tb(err.__traceback__):
        if Path(frame.filename) == Path(path):
            line = frame.lineno
    if isinstance(err, SyntaxError) and err.lineno and Path(err.filename or "") == Path(path):
        line = err.lineno
    message = str(err).splitlines()[0][:300] if str(err).strip() else ""
    missing = (getattr(err, "requested", None) or err.name) if isinstance(err, ModuleNotFoundError) else None
    return {"type": type(err).__name__, "message": message, "line": line, "missing": missing, "index": index,
            "value_error": isinstance(err, ValueError)}


def plain(value: Any) -> Any:
    """`value` as a reply's data: numbers, strings, None, lists (tuples and numeric numpy arrays
    become lists); anything else {'__type__': its type name} (what the host's reader accepts)."""
    if value is None or isinstance(value, (bool, str, int, float)):
        return value
    if type(value).__module__ == "numpy" and getattr(value, "dtype", None) is not None and value.dtype.kind in "biuf":
        return value.tolist()
    if isinstance(value, (tuple, list)):
        return [plain(v) for v in value]
    return {"__type__": type(value).__name__}


def command(value: Any) -> list:
    """A controller's command as [type name, numbers...], or ["bad", type name]."""
    fields = COMMANDS.get(type(value).__name__) if type(value).__module__ == "bots.commands" else None
    if fields is None:
        return ["bad", type(value).__name__]
    return [type(value).__name__, *(float(getattr(value, name)) for name in fields)]


def _entry(module: Any, name: str) -> Any:
    if not hasattr(module, name):
        raise AttributeError(f"your file defines no {name!r} (keep the name the template gives)")
    return getattr(module, name)


def answer(module: Any, objects: dict[int, Any], request: dict[str, Any]) -> Any:
    """The value a request asks for (raises whatever the untrusted code raises)."""
    op = request.get("op")
    if op == "call":
        return plain(_entry(module, request["name"])(*request["args"]))
    if op == "new":
        objects[request["handle"]] = _entry(module, request["name"])(**request["kwargs"])
        return None
    if op == "method":
        target = objects[request["handle"]]
        result = getattr(target, request["name"])(*request["args"])
        attribute = request["attribute"]
        if isinstance(attribute, list):  # several, read once each after the call
            return [plain(getattr(target, name, None)) for name in attribute]
        return plain(getattr(target, attribute) if attribute else result)
    if op == "step":
        return command(objects[request["handle"]].step(request["t"], request["readings"]))
    if op == "feed":
        target, values = objects[request["handle"]], []
        for index, args in enumerate(request["series"]):
            try:
                getattr(target, request["name"])(*args)
                values.append(plain(getattr(target, request["attribute"])))
            except BaseException as err:
                raise FeedError(index) from err
        return values
    raise ValueError(f"unknown request {op!r}")


def name_missing_modules() -> None:
    """Let a failed `import a.b.c` (or `importlib.import_module("a.b.c")`) say a.b.c, not only the
    first missing part `a` (for the message; what is missing is missing from the file system,
    nothing is refused here)."""
    original, original_module = builtins.__import__, importlib.import_module

    def naming(name, globals=None, locals=None, fromlist=(), level=0):
        try:
            return original(name, globals, locals, fromlist, level)
        except ModuleNotFoundError as err:
            if level == 0 and not hasattr(err, "requested"):
                err.requested = name
            raise

    def naming_module(name, package=None):
        try:
            return original_module(name, package)
        except ModuleNotFoundError as err:
            if not name.startswith(".") and not hasattr(err, "requested"):
                err.requested = name
            raise

    builtins.__import__, importlib.import_module = naming, naming_module


def load(path: str) -> Any:
    """The untrusted file as the module `ctsim_student`."""
    spec = importlib.util.spec_from_file_location(STUDENT_MODULE, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[STUDENT_MODULE] = module
    spec.loader.exec_module(module)
    return module


def serve(config: dict[str, Any]) -> None:
    """Confine this process, load the file, answer requests until the host closes the pipe."""
    import confine  # the guest's siblings, on its path beside it (no package, nothing of the project)
    import wire

    limits = config["limits"]
    confine.set_limits(limits["cpu"], limits["memory"], limits["files"], limits["processes"])
    confined = confine.forbid_new_tasks()
    for name in config["preload"]:  # the guest's own imports first: a numpy.py beside the file cannot replace them
        importlib.import_module(name)
    path = config["code"]
    sys.path[:0] = [str(Path(path).parent)]
    name_missing_modules()
    try:
        module = load(path)
    except BaseException as err:  # noqa: BLE001 (the untrusted code: anything may come)
        wire.send(config["replies"], {"error": describe(err, path), "confined": confined})
        return
    wire.send(config["replies"], {"ok": None, "confined": confined})
    objects: dict[int, Any] = {}
    while True:
        try:
            request = wire.receive(config["requests"], REQUEST_LIMIT)
        except EOFError:
            return
        try:
            reply = wire.dumps({"ok": answer(module, objects, request)})
        except BaseException as err:  # noqa: BLE001
            reply = wire.dumps({"error": describe(err, path)})
        for stream in (sys.stdout, sys.stderr):
            stream.flush()
        wire.write_all(config["replies"], reply)


def main() -> None:
    """Serve with the configuration in the first argument (its `path` is on sys.path already)."""
    serve(json.loads(sys.argv[1]))
