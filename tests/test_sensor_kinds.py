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
from bots.spec import _LISTS, FloorSensorSpec, RobotSpec


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


def _add_kind(monkeypatch: pytest.MonkeyPatch, kind: SensorKind, before: str) -> type:
    """Add `kind` to the registry as a new sensor's author would: its row, and its field in
    `Readings` (just `before` another; the class returned, standing for the edited one). The
    tables modules derived from the registry when imported (`FRAMED`, `ARRAYS`) are derived
    again and replaced wherever imported, as a fresh import would find them."""
    import sys

    from bots import readings

    specs = [(f.name, f.type, f) for f in dataclasses.fields(Readings)]
    at = [name for name, _, _ in specs].index(before)
    extended = dataclasses.make_dataclass("Readings", [*specs[:at], (kind.field, np.ndarray, dataclasses.field(default_factory=lambda: np.zeros(0, kind.dtype))), *specs[at:]],
                                          slots=True)  # fmt: skip
    kinds = (*KINDS, kind)
    framed = tuple(k for k in kinds if k.frame is not None)
    arrays = tuple(f.name for f in dataclasses.fields(extended) if f.name in {k.field for k in kinds})
    monkeypatch.setitem(sensor_kinds.BY_FIELD, kind.field, kind)
    replaced = {id(KINDS): kinds, id(sensor_kinds.FRAMED): framed, id(readings.ARRAYS): arrays, id(Readings): extended}
    for name, module in list(sys.modules.items()):
        if name.split(".")[0] in ("bots", "sim"):
            for attribute, value in list(vars(module).items()):
                if id(value) in replaced:
                    monkeypatch.setattr(module, attribute, replaced[id(value)])
    return extended


def test_a_made_up_sensor_added_to_the_registry_alone_reaches_the_world_the_frame_the_export_and_the_recording(monkeypatch: pytest.MonkeyPatch):
    """A new kind of floor sensor (a c't-Bot with two more CNY70s, "cliff") is one registry row,
    its `Readings` field and the robot's list of them (a `RobotSpec` field), its kernel the
    floor's: the World packs its sensors into the floor's rows after the line and border
    sensors and reads them with them, and the step's `SensorFrame`, the run's recorded rows, the
    export and the recording hand its values and channels on without a line elsewhere. On a
    black line one reads black (1023), beside it the plain floor (637), as a line sensor does
    (`test_a_black_line_under_one_sensor`)."""
    from sim.analysis.export import _channels
    from sim.views.recording.layout import field_channels
    from sim.world import World
    from sim.world.spec import FloorLine, WorldSpec

    cliff = SensorKind("cliff", "cliff", (), np.int64, "floor", "kernels.sensing.sample_floor", "kernels.noise.add_rounded", "cliff",
                       "cliff sensors (0 white, 1023 black)", "cliff  (0-1023)", observed="fraction", full_scale=1023.0)  # fmt: skip
    extended = _add_kind(monkeypatch, cliff, before="steering")
    with_cliff = dataclasses.make_dataclass("RobotSpec", [("cliff", tuple[FloorSensorSpec, ...], dataclasses.field(default=()))], bases=(RobotSpec,), frozen=True)
    robot = with_cliff(**{f.name: getattr(CTBOT, f.name) for f in dataclasses.fields(RobotSpec)},
                       cliff=(FloorSensorSpec("cliff front", (0.06, 0.012)), FloorSensorSpec("cliff back", (-0.03, -0.05))))  # fmt: skip

    world = World(WorldSpec("floor", (-1, -1, 1, 1), lines=(FloorLine(((-0.5, 0.012), (0.5, 0.012)), width=0.024),)))
    world.add_robot(robot, (0.0, 0.0, 0.0))
    world.add_robot(robot, (0.0, 0.5, 0.0))  # (beside the line: every sensor on the plain floor)
    samples = {name: np.zeros(1, row) for name, row in world.sensor_rows().items()}  # (one sample of a run's rows)
    frame = world.read_all((samples["values"][0], samples["believed"][0], samples["tallies"][0]))
    floor = len(CTBOT.line) + len(CTBOT.border) + len(robot.cliff)
    assert len(frame.arrays["floor"]) == 2 * floor  # the World's floor rows: each robot's line, border, then cliff sensors
    assert isinstance(frame[0], extended)
    assert list(frame[0].cliff) == [1023, 637] and list(frame[0].line) == [1023, 637] and list(frame[0].border) == [637, 637]
    assert list(frame[1].cliff) == [637, 637]
    assert frame.rows("cliff").tolist() == [[1023, 637], [637, 637]]
    assert world.readings_columns(0, samples["values"], samples["believed"], samples["tallies"])["cliff"].tolist() == [[1023, 637]]
    assert _channels(robot, "cliff") == ("cliff front", "cliff back")
    assert field_channels(robot, "cliff") == (("cliff front", "cliff back"), None)
    assert sensor_kinds.groups()["cliff"] == ("cliff sensors (0 white, 1023 black)", ("cliff",))


def test_the_export_and_the_recording_name_a_c_t_bot_s_channels_alike():
    from sim.analysis.export import _channels
    from sim.views.recording.layout import field_channels

    for kind in KINDS:
        if not kind.chassis_only:
            assert _channels(CTBOT, kind.field) == field_channels(CTBOT, kind.field)[0], kind.field
    assert _channels(CTBOT, "ir_raw") == tuple(s.name for s in CTBOT.ir)
    assert _channels(CTBOT.with_changes(mouse=None), "mouse_counts") == ()


def test_the_odometry_names_the_tallies_in_the_registry_s_order():
    """`bots.odometry.layout.TALLY` (the counts' places in a step's tallies) follows the
    registry's packing of its tallies array: the encoder ticks (left, right), then the mouse
    counts (forward, lateral)."""
    from bots.odometry.layout import TALLY
    from bots.sensor_kinds import FRAMED

    packed = [(kind.field, kind.width(CTBOT)) for kind in FRAMED if kind.frame == "tallies"]
    assert packed == [("encoder_ticks", 2), ("mouse_counts", 2)]
    assert (TALLY.left, TALLY.right, TALLY.forward, TALLY.lateral) == (0, 1, 2, 3)
