"""The one format both sides of the sandbox speak: length-prefixed JSON messages of plain data.

A message is 4 bytes of big-endian length, then that many bytes of UTF-8 JSON. Values are JSON's
own (null, booleans, numbers with NaN and ±Infinity, strings, lists, objects with string keys) and
three tagged objects:

    {"__array__": [dtype, shape, flat values]}    a numpy array; dtype "float64", "int64" or "bool"
    {"__tuple__": [values]}                        a tuple
    {"__record__": [type name, {field: value}]}    an object of named fields (a dataclass's fields
                                                   and properties), read-only on the other side
    {"__type__": type name}                        a value of another kind, not sent (`Opaque`)

Nothing else crosses: no pickle, no code. A reader refuses a message longer than its limit before
it reads the body. This is what the host sends and the guest reads; the guest's replies are read
by the host with `sim.sandbox.reply`, which accepts far less (the untrusted code may forge them). This module imports the standard library only (numpy when an array comes), so
that the guest inside the sandbox can use it as it is.
"""

from __future__ import annotations

import json
import math
import os
import struct
from collections.abc import Callable
from typing import Any

HEADER = struct.Struct(">I")
DTYPES = ("float64", "int64", "bool")


class WireError(ValueError):
    """A message that is not plain data of this format (too long, not JSON, a bad tag)."""


class Record:
    """An object of named, read-only fields rebuilt from a `__record__` (a RobotSpec, Readings...)."""

    def __init__(self, type_name: str, fields: dict[str, Any]):
        object.__setattr__(self, "_type", type_name)
        object.__setattr__(self, "_fields", tuple(fields))
        for name, value in fields.items():
            object.__setattr__(self, name, value)

    def __setattr__(self, name: str, value: Any) -> None:
        raise AttributeError(f"{self._type} is read-only")

    def __repr__(self) -> str:
        return f"{self._type}({', '.join(f'{k}={getattr(self, k)!r}' for k in self._fields)})"


_NAMES: dict[type, list[str]] = {}


class Opaque:
    """What stands for a value the other side could not send as plain data: its type's name."""

    def __init__(self, type_name: str):
        self.type_name = type_name

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Opaque) and other.type_name == self.type_name

    def __repr__(self) -> str:
        return f"<a {self.type_name}>"


def _names(cls: type) -> list[str]:
    """A dataclass's fields, then its public properties (cached ones too): what a reader of the
    object may expect. Known once per class."""
    if cls not in _NAMES:
        import dataclasses
        from functools import cached_property

        properties = [name for klass in reversed(cls.__mro__) for name, member in vars(klass).items()
                      if not name.startswith("_") and isinstance(member, (property, cached_property))]  # fmt: skip
        _NAMES[cls] = [f.name for f in dataclasses.fields(cls)] + properties
    return _NAMES[cls]


def encode(value: Any) -> Any:
    """`value` as JSON-ready plain data; numpy scalars become numbers, dataclasses records.
    Anything else is refused (the host sends only what it means to send)."""
    if value is None or isinstance(value, (bool, str, int, float)):
        return value
    if isinstance(value, list):
        return [encode(v) for v in value]
    if isinstance(value, tuple):
        return {"__tuple__": [encode(v) for v in value]}
    if isinstance(value, dict):
        return {str(k): encode(v) for k, v in value.items()}
    if type(value).__module__ == "numpy":
        return _encode_numpy(value)
    if hasattr(type(value), "__dataclass_fields__") and not isinstance(value, type):
        return {"__record__": [type(value).__name__, {n: encode(getattr(value, n)) for n in _names(type(value))}]}
    raise WireError(f"cannot send a {type(value).__name__} as plain data")


def _encode_numpy(value: Any) -> Any:
    import numpy as np

    if isinstance(value, np.generic):
        return value.item()
    kind = value.dtype.kind
    if kind not in "biuf":
        raise WireError(f"cannot send an array of {value.dtype} as plain data")
    dtype = {"b": "bool", "i": "int64", "u": "int64", "f": "float64"}[kind]
    return {"__array__": [dtype, list(value.shape), value.astype(dtype).ravel().tolist()]}


def decode(value: Any) -> Any:
    """Plain data from JSON back to Python: arrays, tuples and records rebuilt; a WireError for a
    malformed tag."""
    if isinstance(value, list):
        return [decode(v) for v in value]
    if not isinstance(value, dict):
        return value
    if len(value) == 1:
        (tag, body), = value.items()
        if tag == "__array__":
            return _decode_array(body)
        if tag == "__type__" and isinstance(body, str):
            return Opaque(body[:100])
        if tag == "__tuple__" and isinstance(body, list):
            return tuple(decode(v) for v in body)
        if tag == "__record__" and isinstance(body, list) and len(body) == 2 and isinstance(body[0], str) and isinstance(body[1], dict):
            return Record(body[0], {str(k): decode(v) for k, v in body[1].items() if str(k).isidentifier()})
        if tag.startswith("__") and tag.endswith("__"):
            raise WireError(f"malformed {tag} in a message")
    return {k: decode(v) for k, v in value.items()}


def _decode_array(body: Any) -> Any:
    import numpy as np

    if not (isinstance(body, list) and len(body) == 3 and body[0] in DTYPES and isinstance(body[1], list)
            and all(isinstance(n, int) and n >= 0 for n in body[1]) and isinstance(body[2], list)):  # fmt: skip
        raise WireError("malformed __array__ in a message")
    dtype, shape, flat = body
    if math.prod(shape) != len(flat) or not all(isinstance(v, (int, float)) for v in flat):
        raise WireError("an __array__ whose values do not fill its shape with numbers")
    try:
        return np.array(flat, dtype=dtype).reshape(shape)
    except (OverflowError, ValueError):
        raise WireError("an __array__ whose values do not fit its dtype") from None


def dumps(value: Any) -> bytes:
    """One message: header and JSON body of `value` (encoded)."""
    body = json.dumps(encode(value), separators=(",", ":")).encode("utf-8")
    return HEADER.pack(len(body)) + body


def loads(body: bytes) -> Any:
    """A message body back to plain data; a WireError for anything that is not."""
    try:
        return decode(json.loads(body.decode("utf-8")))
    except WireError:
        raise
    except (ValueError, RecursionError) as err:  # UnicodeDecodeError and JSONDecodeError are ValueErrors
        raise WireError(f"not a message of plain data ({type(err).__name__})") from None


def send(fd: int, value: Any) -> None:
    """Write one message to the file descriptor `fd` (blocking)."""
    write_all(fd, dumps(value))


def write_all(fd: int, data: bytes) -> None:
    """Write all of `data` to `fd` (blocking)."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def receive(fd: int, limit: int, wait: Callable[[int], None] | None = None) -> Any:
    """Read one message from `fd`; EOFError when the writer is gone, WireError for a message over
    `limit` bytes or not of plain data. `wait(fd)`, if given, is called before each read (to
    raise when a deadline passes); without it the read blocks."""
    return loads(receive_body(fd, limit, wait))


def receive_body(fd: int, limit: int, wait: Callable[[int], None] | None = None) -> bytes:
    """One message's body from `fd`, not decoded (as `receive`; for a reader of its own)."""
    (length,) = HEADER.unpack(read_exactly(fd, HEADER.size, wait))
    if length > limit:
        raise WireError(f"a message of {length} bytes (the limit is {limit})")
    return read_exactly(fd, length, wait)


def read_exactly(fd: int, n: int, wait: Callable[[int], None] | None = None) -> bytes:
    """`n` bytes from `fd`; EOFError if it closes first."""
    chunks, left = [], n
    while left:
        if wait is not None:
            wait(fd)
        chunk = os.read(fd, min(left, 1 << 20))
        if not chunk:
            raise EOFError
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)
