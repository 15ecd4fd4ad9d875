"""The sensor registry (`bots.sensor_kinds`) is the one list of reading kinds: it matches
`Readings`, the robot file's sections, the world's kernels and the bridge's packets, and the
parts that iterate over it pick up a kind added to it and nowhere else."""

from __future__ import annotations

import dataclasses
import importlib
from typing import get_args, get_origin, get_type_hints

import numpy as np
import pytest

from bots import sensor_kinds
from bots.ctbot import CTBOT
from bots.readings import Readings
from bots.sensor_kinds import KINDS, SensorKind, groups, sections
from bots.spec import _LISTS, RobotSpec


def _resolve(dotted: str):
    """The object a registry row names under sim.world (module path, then attributes)."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            found = importlib.import_module("sim.world." + ".".join(parts[:cut]))
        except ModuleNotFoundError:
            continue
        for name in parts[cut:]:
            found = getattr(found, name)
        return found
    raise AssertionError(f"{dotted} names nothing under sim.world")


def test_the_registry_lists_every_readings_array_once():
    arrays = [f.name for f in dataclasses.fields(Readings) if f.name not in ("time", "failures")]
    assert sorted(kind.field for kind in KINDS) == sorted(arrays)


def test_its_sections_kernels_and_packets_exist():
    from sim.bridge import protocol

    declared = {name for name, hint in get_type_hints(RobotSpec).items() if get_origin(hint) is tuple and dataclasses.is_dataclass(get_args(hint)[0])}
    assert set(sections()) == set(_LISTS) == declared  # (every list of sensors a robot declares is a kind's section, and only those)
    for kind in KINDS:
        assert callable(_resolve(kind.kernel)), kind.kernel
        assert kind.noise is None or callable(_resolve(kind.noise)), kind.noise
        assert kind.packet is None or isinstance(getattr(protocol, kind.packet), str), kind.packet
        assert kind.dtype(0).dtype == getattr(Readings(), kind.field).dtype, kind.field


def test_the_full_scales_are_the_sensors_adc_tops():
    from sim.world.sensors import CNY70_MAX, LDR_MAX

    tops = {"line": CNY70_MAX, "border": CNY70_MAX, "light": LDR_MAX}
    assert {kind.field: kind.full_scale for kind in KINDS if kind.observed == "fraction"} == tops


def test_a_group_has_one_title():
    for kind in KINDS:
        assert groups()[kind.group][0] == kind.title, kind.field


def test_a_made_up_sensor_added_to_the_registry_alone_reaches_the_export_and_the_recording(monkeypatch: pytest.MonkeyPatch):
    """A kind of one row (here a bumper pair, as c't-Sim's has none) gets its channels in the
    export's columns and the recording's, and its plot, without a line elsewhere."""
    from sim.analysis.export import _channels
    from sim.views.recording.layout import field_channels

    bumper = SensorKind("bumper", None, ("left", "right"), np.int64, "tallies", "kernels.motion.measure", None, "bumpers",
                        "bumpers (0 free, 1 pressed)", "bumpers")  # fmt: skip
    monkeypatch.setattr(sensor_kinds, "KINDS", (*KINDS, bumper))
    monkeypatch.setitem(sensor_kinds.BY_FIELD, "bumper", bumper)
    assert _channels(CTBOT, "bumper") == ("left", "right")
    assert field_channels(CTBOT, "bumper") == (("left", "right"), None)
    assert sensor_kinds.groups()["bumpers"] == ("bumpers (0 free, 1 pressed)", ("bumper",))


def test_the_export_and_the_recording_name_a_c_t_bot_s_channels_alike():
    from sim.analysis.export import _channels
    from sim.views.recording.layout import field_channels

    for kind in KINDS:
        if not kind.chassis_only:
            assert _channels(CTBOT, kind.field) == field_channels(CTBOT, kind.field)[0], kind.field
    assert _channels(CTBOT, "ir_raw") == tuple(s.name for s in CTBOT.ir)
    assert _channels(CTBOT.with_changes(mouse=None), "mouse_counts") == ()
