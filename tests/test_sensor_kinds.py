"""The sensor registry (`bots.sensor_kinds`) is the one list of reading kinds: it matches
`Readings`, the robot file's sections, the world's kernels and the bridge's packets, and the
parts that iterate over it pick up a kind added to it and nowhere else."""

from __future__ import annotations

import dataclasses
import importlib
from typing import get_args, get_origin, get_type_hints

from bots.ctbot import CTBOT
from bots.readings import Readings
from bots.sensor_kinds import KINDS, groups, sections
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
        assert kind.section is None or _LISTS[kind.section].__name__ == kind.sensor, kind.field  # (kinds of one section agree)
        assert kind.meaning, kind.field  # (its line of `Readings`' docstring)
        assert callable(_resolve(kind.kernel)), kind.kernel
        assert kind.noise is None or callable(_resolve(kind.noise)), kind.noise
        assert kind.packet is None or isinstance(getattr(protocol, kind.packet), str), kind.packet
        assert kind.dtype(0).dtype == getattr(Readings(), kind.field).dtype, kind.field


def test_the_bridge_sends_each_packet_of_the_registry_once_in_c_t_sim_s_order():
    """The bridge's table of a step's packets (`sim.bridge.firmware.BLOCK`, c't-Sim's wire order)
    holds every registry kind's packet once, and a kind's `wire` names its channels."""
    from sim.bridge import protocol
    from sim.bridge.firmware import BLOCK

    for kind in KINDS:
        assert kind.packet is None or BLOCK.count(getattr(protocol, kind.packet)) == 1, kind.field
        assert kind.wire is None or all(name.removeprefix("-") in kind.channels for name in kind.wire), kind.field


def test_the_full_scales_are_the_sensors_adc_tops():
    from sim.world.sensors import CNY70_MAX, LDR_MAX

    tops = {"line": CNY70_MAX, "border": CNY70_MAX, "light": LDR_MAX}
    assert {kind.field: kind.full_scale for kind in KINDS if kind.observed == "fraction"} == tops


def test_a_group_has_one_title():
    for kind in KINDS:
        assert groups()[kind.group][0] == kind.title, kind.field


CLIFF = """\
    SensorKind("cliff", "cliff", (), np.int64, "floor", "kernels.sensing.sample_floor", "kernels.noise.add_rounded", "cliff",
               "cliff sensors (0 white, 1023 black)", "cliff  (0-1023)", meaning="CNY70s looking for a drop, 0 (white) .. 1023 (black or hole)",
               sensor="FloorSensorSpec", observed="fraction", full_scale=1023.0),
"""
"""A made-up kind of floor sensor (a c't-Bot with two more CNY70s), as its author would write its row."""
CLIFF_BEFORE = '    SensorKind("steering"'
"""The registry's line the row goes before."""

ADDED = """
import dataclasses, json, sys, types
from pathlib import Path

path = Path(sys.argv[1])
source = path.read_text()
registry = types.ModuleType("bots.sensor_kinds")  # (the registry file as edited: one row more, and no other file)
registry.__file__ = str(path)
sys.modules[registry.__name__] = registry
exec(compile(source.replace(sys.argv[3], sys.argv[2] + sys.argv[3], 1), str(path), "exec"), registry.__dict__)

import numpy as np
from bots.ctbot import CTBOT
from bots.readings import Readings
from bots.spec import FloorSensorSpec, robot_from_dict
from sim.analysis.export import _channels
from sim.views.recording.layout import field_channels
from sim.world import World
from sim.world.spec import FloorLine, WorldSpec

cliff = robot_from_dict({"cliff": [{"name": "cliff front", "position": [0.06, 0.012]}, {"name": "cliff back", "position": [-0.03, -0.05]}],
                         **{key: getattr(CTBOT, key) for key in ("name", "wheel_diameter", "track_width", "body_radius")}}).cliff
robot = dataclasses.replace(CTBOT, cliff=cliff)
world = World(WorldSpec("floor", (-1, -1, 1, 1), lines=(FloorLine(((-0.5, 0.012), (0.5, 0.012)), width=0.024),)))
world.add_robot(robot, (0.0, 0.0, 0.0))
world.add_robot(robot, (0.0, 0.5, 0.0))  # (beside the line: every sensor on the plain floor)
samples = {name: np.zeros(1, row) for name, row in world.sensor_rows().items()}  # (one sample of a run's rows)
frame = world.read_all((samples["values"][0], samples["believed"][0], samples["tallies"][0]))
print(json.dumps({
    "sensors": [type(sensor).__name__ for sensor in cliff],
    "floor": len(frame.arrays["floor"]),
    "readings": isinstance(frame[0], Readings) and Readings.__doc__.count("cliff: CNY70s"),
    "cliff": [frame[0].cliff.tolist(), frame[1].cliff.tolist()], "line": frame[0].line.tolist(), "border": frame[0].border.tolist(),
    "rows": frame.rows("cliff").tolist(),
    "recorded": world.readings_columns(0, samples["values"], samples["believed"], samples["tallies"])["cliff"].tolist(),
    "export": _channels(robot, "cliff"), "recording": field_channels(robot, "cliff")[0],
    "group": registry.groups()["cliff"],
}))
"""
"""The made-up sensor's check, in a process of its own whose registry module is the file's text with
the row added (argv: the file, the row, the line it goes before): what a fresh import finds."""


def test_a_made_up_sensor_added_to_the_registry_alone_reaches_the_robot_file_the_world_the_frame_the_export_and_the_recording():
    """A new kind of floor sensor (a c't-Bot with two more CNY70s, "cliff") is one registry row
    and nothing else: its kernel is the floor's, and with that row alone, in a process that
    imports everything afresh, the robot file has a `[[cliff]]` list of floor sensors (a
    `RobotSpec` field), `Readings` a `cliff` field with its line of the docstring, the World packs
    its sensors into the floor's rows after the line and border sensors and reads them with them,
    and the step's `SensorFrame`, the run's recorded rows, the export and the recording hand its
    values and channels on. On a black line one reads black (1023), beside it the plain floor
    (637), as a line sensor does (`test_a_black_line_under_one_sensor`)."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    registry = root / "bots" / "sensor_kinds.py"
    assert registry.read_text().count(CLIFF_BEFORE) == 1
    done = subprocess.run([sys.executable, "-c", ADDED, str(registry), CLIFF, CLIFF_BEFORE], capture_output=True, text=True, cwd=root,
                          env={**os.environ, "PYTHONPATH": str(root)}, timeout=600)  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    found = json.loads(done.stdout.splitlines()[-1])
    assert found["sensors"] == ["FloorSensorSpec", "FloorSensorSpec"]
    assert found["floor"] == 2 * (len(CTBOT.line) + len(CTBOT.border) + 2)  # the World's floor rows: each robot's line, border, then cliff sensors
    assert found["readings"] == 1
    assert found["cliff"] == [[1023, 637], [637, 637]] and found["line"] == [1023, 637] and found["border"] == [637, 637]
    assert found["rows"] == [[1023, 637], [637, 637]]
    assert found["recorded"] == [[1023, 637]]
    assert found["export"] == found["recording"] == ["cliff front", "cliff back"]
    assert found["group"] == ["cliff sensors (0 white, 1023 black)", ["cliff"]]


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
