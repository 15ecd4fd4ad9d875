"""Issue 3: IR distance sensors read hand-computed distances to walls and other robots through the
characteristic curves; the curves match c't-Sim's measured files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from bots.ctbot import CTBOT
from bots.spec import IRSensorSpec
from sim.world import World
from sim.world.sensors import builtin_gp2d12, load_ir_curve
from sim.world.spec import Wall, WorldSpec

SHARED = Path(__file__).resolve().parents[2] / "shared"
CURVES = SHARED / "ctsim" / "characteristics"
needs_shared = pytest.mark.skipif(not CURVES.is_dir(), reason=f"c't-Sim characteristic files not found at {CURVES} (../shared absent)")
SENSOR_X, SENSOR_Y = CTBOT.ir[0].position  # 0.0554 forward, 0.036 to the left


def read_file(name: str) -> tuple[np.ndarray, np.ndarray]:
    """(distance m, value) rows of a characteristic file, parsed here independently."""
    rows = []
    for line in (CURVES / name).read_text(encoding="latin-1").splitlines()[2:]:
        cells = [c.strip() for c in line.split(";") if c.strip()]
        if cells:
            rows.append((float(cells[0]) / 100, float(cells[1])))
    table = np.array(rows)
    return table[:, 0], table[:, 1]


def inverse_resolution(curve, distance: float) -> float:
    """Distance (m) that half a raw unit spans on the curve around `distance` (the steeper-less of
    the two table segments next to it): how far a rounded raw value can move the inverse."""
    k = int(np.searchsorted(curve.distance, distance))
    slopes = [
        abs((curve.raw[j + 1] - curve.raw[j]) / (curve.distance[j + 1] - curve.distance[j]))
        for j in (k - 2, k - 1, k)
        if 0 <= j < len(curve.distance) - 1
    ]
    return 0.5 / min(slopes)


def wall_world(distance_from_sensor: float, heading: float = 0.0) -> tuple[World, object]:
    """A robot at the origin facing `heading`, with a wall across its way whose face is
    `distance_from_sensor` ahead of the IR sensors' plane."""
    c, s = math.cos(heading), math.sin(heading)
    face = SENSOR_X + distance_from_sensor
    local = ((face, -1.0), (face + 0.05, -1.0), (face + 0.05, 1.0), (face, 1.0))
    wall = Wall(tuple((c * x - s * y, s * x + c * y) for x, y in local))
    world = World(WorldSpec("w", (-3, -3, 3, 3), walls=(wall,)))
    return world, world.add_robot(CTBOT, (0.0, 0.0, heading))


@pytest.mark.parametrize("heading", [0.0, 0.7, -2.3])
@pytest.mark.parametrize("distance", [0.08, 0.1, 0.1537, 0.3, 0.42, 0.6, 0.79])
def test_ir_reads_the_curve_at_the_distance_to_a_wall(distance, heading):
    """Facing a wall at a known distance (any heading): ir_raw is the curve's value at exactly that
    distance from each sensor, and from 0.1 m on ir_distance gives it back within the curve's
    inverse resolution."""
    world, robot = wall_world(distance, heading)
    r = world.read_all()[0]
    for k, curve in enumerate(robot.ir_curves):
        assert r.ir_raw[k] == curve.lookup(distance)
        if distance >= 0.1:  # below, the sensor folds back: its value is that of a farther distance
            assert abs(r.ir_distance[k] - distance) <= inverse_resolution(curve, distance) + 1e-12


def test_ir_errors_stay_small_over_the_range():
    """Over 0.1-0.8 m in 1 cm steps the inverse error stays within the resolution bound; the worst
    case is reported in the assertion message."""
    worst = 0.0
    for distance in np.arange(0.10, 0.80, 0.01):
        world, robot = wall_world(float(distance))
        r = world.read_all()[0]
        error = np.abs(r.ir_distance - distance)
        worst = max(worst, float(error.max()))
        assert all(e <= inverse_resolution(c, distance) + 1e-12 for e, c in zip(error, robot.ir_curves))
    assert worst < 0.02, f"worst IR distance error {worst * 1000:.1f} mm"


def test_ir_sees_another_robot_and_skips_its_own_body():
    """A robot 0.3 m ahead (slightly to the side): each sensor reads the hand-computed distance to
    the other body's circle; the sensors sit inside their own body, which they do not see."""
    world = World(WorldSpec("open", (-2, -2, 2, 2)))
    me = world.add_robot(CTBOT, (0.0, 0.0, 0.0))
    cx, cy, radius = 0.3, 0.02, CTBOT.body_radius
    world.add_robot(CTBOT, (cx, cy, 1.0))
    r = world.read_all()[0]
    for k, sensor in enumerate(CTBOT.ir):
        sx, sy = sensor.position
        expected = (cx - sx) - math.sqrt(radius**2 - (sy - cy) ** 2)
        assert abs(world.ray_distance(me, (sx, sy), 0.0) - expected) < 1e-9
        assert r.ir_raw[k] == me.ir_curves[k].lookup(expected)
        assert abs(r.ir_distance[k] - expected) <= inverse_resolution(me.ir_curves[k], expected) + 1e-12


def test_ir_with_nothing_in_range_reads_the_far_value():
    """Nothing within 0.85 m: the ray returns inf, ir_raw the curve's last value, ir_distance nan."""
    world = World(WorldSpec("open", (-2, -2, 2, 2)))
    me = world.add_robot(CTBOT, (0.0, 0.0, 0.0))
    r = world.read_all()[0]
    assert world.ray_distance(me, (SENSOR_X, SENSOR_Y), 0.0) == math.inf
    assert [int(v) for v in r.ir_raw] == [int(c.raw[-1]) for c in me.ir_curves]
    assert np.all(np.isnan(r.ir_distance))


@needs_shared
@pytest.mark.parametrize("name", ["gp2d12Left.txt", "gp2d12Right.txt", "gp2y0a60Left.txt", "vl53l0xRight.txt"])
def test_curve_files_are_matched_exactly_and_interpolated_with_rounding(name):
    """A characteristic file is reproduced exactly at its tabulated distances and interpolated
    linearly, then rounded, between them (checked at 2000 random distances, ties excepted)."""
    distance, value = read_file(name)
    curve = load_ir_curve(CURVES / name)
    assert np.array_equal(curve.lookup(distance), value.astype(int))
    probe = np.random.default_rng(5).uniform(distance[0], distance[-1], 2000)
    k = np.clip(np.searchsorted(distance, probe, side="right") - 1, 0, len(distance) - 2)
    w = (probe - distance[k]) / (distance[k + 1] - distance[k])
    exact = value[k] + w * (value[k + 1] - value[k])
    clear = np.abs(exact - np.floor(exact) - 0.5) > 1e-6
    assert np.array_equal(curve.lookup(probe)[clear], np.floor(exact[clear] + 0.5).astype(int))


@needs_shared
def test_a_sensor_naming_a_file_uses_it_and_left_and_right_differ():
    """IRSensorSpec(curve="gp2d12Left.txt") resolves in the shared folder: at 0.3 m the robot's left
    and right sensors read the files' 206 and 191; at 0.8 m 110 and 76."""
    left, right = CTBOT.ir
    spec = CTBOT.with_changes(
        ir=(IRSensorSpec(left.name, left.position, curve="gp2d12Left.txt"), IRSensorSpec(right.name, right.position, side="right", curve="gp2d12Right.txt"))
    )
    for distance, expected in ((0.3, [206, 191]), (0.8, [110, 76]), (0.1, [525, 511])):
        world = World(WorldSpec("w", (-3, -3, 3, 3), walls=(Wall(((SENSOR_X + distance, -1), (1.5, -1), (1.5, 1), (SENSOR_X + distance, 1))),)))
        world.add_robot(spec, (0.0, 0.0, 0.0))
        assert list(world.read_all()[0].ir_raw) == expected


@needs_shared
@pytest.mark.parametrize("side", ["left", "right"])
def test_builtin_curve_stays_close_to_the_measured_files(side):
    """The built-in GP2D12 fit stays within 12 raw units of the measured file between 0.1 and 0.8 m."""
    measured = load_ir_curve(CURVES / f"gp2d12{side.title()}.txt")
    d = np.linspace(0.1, 0.8, 701)
    gap = np.abs(builtin_gp2d12(side).lookup(d) - measured.lookup(d))
    assert gap.max() <= 12, f"{side}: {gap.max()} raw units at {d[gap.argmax()]:.3f} m"
