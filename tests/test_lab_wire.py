"""The host's reader of a guest's reply (sim.sandbox.reply) takes data only: whatever bytes the
untrusted code writes to the reply pipe, the host gets numbers, strings and lists back, or a
WireError (the student's protocol error); never an object that names an attribute, never a
numpy array over memory, never an exception of another kind."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.sandbox import guest, reply, wire
from sim.sandbox.wire import Opaque, WireError

ERROR = {"type": "ValueError", "message": "m", "line": 3, "missing": None, "index": None, "value_error": True}

json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=5) | st.dictionaries(st.text(max_size=12) | st.sampled_from(
        ["ok", "error", "confined", "__type__", "__array__", "__record__", "__class__", "__array_interface__", *ERROR]), inner, max_size=5),
    max_leaves=30,
)  # fmt: skip


def body(value) -> bytes:
    return json.dumps(value).encode()


def only_plain(value) -> bool:
    if isinstance(value, list):
        return all(only_plain(v) for v in value)
    return value is None or type(value) in (bool, int, float, str, Opaque)


@given(st.binary(max_size=300))
def test_any_bytes_are_a_reply_or_a_wire_error(data: bytes) -> None:
    try:
        reply.read(data)
    except WireError:
        pass


@settings(max_examples=300)
@given(st.one_of(json_values, st.fixed_dictionaries({"ok": json_values}), st.fixed_dictionaries({"error": json_values}),
                 st.fixed_dictionaries({"ok": json_values, "confined": json_values})))  # fmt: skip
def test_any_json_is_a_reply_of_plain_data_or_a_wire_error(value) -> None:
    try:
        answer = reply.read(body(value))
    except WireError:
        return
    assert set(answer) <= {"ok", "error", "confined"}
    if "ok" in answer:
        assert only_plain(answer["ok"])
        try:  # what the checks do with it: numbers copied, or refused as not numbers
            np.asarray(answer["ok"], dtype=np.float64)
        except (TypeError, ValueError, OverflowError):
            pass
    else:
        assert answer["error"].keys() == ERROR.keys()


@given(st.recursive(st.floats() | st.integers(-(2**62), 2**62) | st.text(max_size=10) | st.none(),
                    lambda inner: st.lists(inner, max_size=4) | st.tuples(inner, inner), max_leaves=20))  # fmt: skip
def test_what_the_guest_sends_arrives_as_the_same_data(value) -> None:
    back = reply.read(wire.dumps({"ok": guest.plain(value)})[wire.HEADER.size:])["ok"]
    assert json.dumps(back, default=repr) == json.dumps(guest.plain(value), default=repr)


def test_numpy_arrays_and_objects_of_other_kinds_arrive_as_lists_and_type_names() -> None:
    sent = guest.plain([np.arange(4.0).reshape(2, 2), np.int64(3), {"a": 1}, object(), (1, 2)])
    assert reply.read(wire.dumps({"ok": sent})[wire.HEADER.size:])["ok"] == [[[0.0, 1.0], [2.0, 3.0]], 3, Opaque("dict"), Opaque("object"), [1, 2]]


FORGED = {
    "array interface record": {"ok": {"__record__": ["R", {"__array_interface__": {"data": [0, False], "shape": [1 << 20], "typestr": "<f8"}}]}},
    "array past its end": {"ok": {"__array__": ["float64", [1 << 20], [1.0]]}},
    "a field named __class__": {"ok": {"__record__": ["R", {"__class__": 1}]}},
    "a dict of numbers": {"ok": {"x": 1.0}},
    "a type tag with more fields": {"ok": {"__type__": "float", "__array_interface__": 1}},
    "an error with a dunder": {"error": ERROR | {"__class__": 1}},
    "an error missing a field": {"error": {k: v for k, v in ERROR.items() if k != "line"}},
    "a line that is true": {"error": ERROR | {"line": True}},
    "a message that is a list": {"error": ERROR | {"message": ["x"]}},
    "both ok and error": {"ok": 1, "error": ERROR},
    "a stray field": {"ok": 1, "note": "x"},
    "confined as a string": {"ok": None, "confined": "yes"},
    "not an object": [1, 2, 3],
}


@pytest.mark.parametrize("forged", FORGED.values(), ids=FORGED.keys())
def test_each_forged_reply_is_a_wire_error(forged) -> None:
    with pytest.raises(WireError):
        reply.read(body(forged))


@pytest.mark.parametrize("data", [b"[" * 200_000, b'{"ok": ' + b"[" * 40 + b"]" * 40 + b"}", b'{"ok": ' + b"9" * 5000 + b"}",
                                  b"\xff\xfe", b'{"ok": NaN', b""])  # fmt: skip
def test_deep_huge_or_broken_replies_are_wire_errors(data: bytes) -> None:
    with pytest.raises(WireError):
        reply.read(data)


def test_long_strings_are_cut_and_numbers_kept_exactly() -> None:
    answer = reply.read(body({"error": ERROR | {"message": "x" * 600_000}}))
    assert len(answer["error"]["message"]) == reply.STRING
    assert reply.read(b'{"ok": [NaN, Infinity, -0.0, 1e308, 12345678901234567890]}')["ok"][3:] == [1e308, 12345678901234567890]
