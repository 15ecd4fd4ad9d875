"""Issue 16: the compiled sensor paths give the bits of the reference ones: IR curve lookup and
inverse (`kernels.sensing.ir_values` against `IRCurve`), the IR grid broad phase against every circle,
and noise drawn in blocks against one draw at a time."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bots.ir_curve import IRCurve, gp2d12
from sim.world import layout
from sim.world.kernels.grids import gridded
from sim.world.kernels.sensing import ir_values, sense_ir
from sim.world.noise import NormalBlocks

RANGES = [(0.1, 0.8), (0.05, 0.5)]


def curves(curve: IRCurve, inverse: np.ndarray) -> layout.Curves:
    """One curve with one range's inverse, as the IR kernels take it."""
    ends = layout.CURVE_ENDS.new(1)
    ends["last"], ends["lowest"] = len(curve.per_cm) - 1, curve.raw_range()[0]
    return layout.Curves(0.85, curve.per_cm[None], ends, np.array([curve.beyond], dtype=np.float32), inverse[None])


def ir_sensors(n: int, noise_row: int) -> np.ndarray:
    """SENSORS rows of `n` IR sensors on curve 0 with this noise row (-1: none)."""
    sensors = layout.SENSORS.new(n)
    sensors["noise_row"] = noise_row
    return sensors


def compiled(curve: IRCurve, low: float, high: float, distance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`kernels.sensing.ir_values` for one curve and range, without noise."""
    n = len(distance)
    raw, believed = np.empty(n, dtype=np.int64), np.empty(n)
    no_noise = layout.Noise(np.zeros(0, dtype=np.int64), np.zeros(0), np.zeros((0, 1)), np.zeros(0, dtype=np.int64))
    ir_values(distance, ir_sensors(n, -1), no_noise, curves(curve, curve.inverse_table(low, high)), raw, believed)
    return raw, believed


@pytest.mark.parametrize("side", ["left", "right"])
@pytest.mark.parametrize("low, high", RANGES)
def test_ir_values_are_the_curves_lookup_and_inverse(side, low, high):
    """Every 0.1 mm from 0 to 1 m, each whole centimetre (table rows), nothing in view (inf) and
    nan: the same raw values and the same believed distances (nan where the inverse gives nan)."""
    curve = gp2d12(side)
    distance = np.concatenate((np.linspace(0.0, 1.0, 10001), np.arange(0, 100) / 100, [math.inf, math.nan]))
    raw, believed = compiled(curve, low, high, distance)
    expected_raw = curve.lookup(distance)
    assert np.array_equal(raw, expected_raw)
    assert np.array_equal(believed, curve.distance_from_raw(expected_raw, low, high), equal_nan=True)


@given(st.lists(st.floats(0.0, 2.0), min_size=1, max_size=50), st.sampled_from(["left", "right"]))
@settings(max_examples=100)
def test_ir_values_at_random_distances(distances, side):
    curve = gp2d12(side)
    distance = np.array(distances)
    raw, believed = compiled(curve, 0.1, 0.8, distance)
    assert np.array_equal(raw, curve.lookup(distance))
    assert np.array_equal(believed, curve.distance_from_raw(raw), equal_nan=True)


def test_ir_noise_consumes_one_normal_per_sensor_that_sees_something():
    """A noisy sensor with nothing in view takes no normal (as the per-step draw it replaces);
    one with a wall in view adds std times its next normal."""
    curve = gp2d12("left")
    normals = np.array([[0.5, -1.0, 2.0]])
    used = np.zeros(1, dtype=np.int64)
    raw, believed = np.empty(1, dtype=np.int64), np.empty(1)
    for distance, expected_used in ((math.inf, 0), (0.3, 1), (math.inf, 1), (0.3, 2)):
        ir_values(np.array([distance]), ir_sensors(1, 0), layout.Noise(np.zeros(1, dtype=np.int64), np.array([0.01]), normals, used), curves(curve, curve.inverse_table()), raw, believed)
        assert used[0] == expected_used
    assert raw[0] == curve.lookup(np.array([0.3 + 0.01 * -1.0]))[0]


def crowd(seed: int, count: int, spread: float, sensors: int) -> tuple:
    rng = np.random.default_rng(seed)
    circles = layout.CIRCLES.new(count)
    centres = rng.uniform(-spread, spread, (count, 2))
    circles["x"], circles["y"], circles["radius"], circles["owner"] = centres[:, 0], centres[:, 1], rng.uniform(0.01, 0.08, count), rng.integers(-1, count, count)
    origins = rng.uniform(-spread, spread, (sensors, 2))
    look = rng.uniform(-math.pi, math.pi, sensors)
    cone = rng.choice([0.0, math.radians(3.0), 0.5, 1.2], sensors)
    owner = rng.integers(0, count, sensors)
    return origins, look, cone, owner, circles


@given(st.integers(0, 2**32 - 1), st.integers(1, 300), st.sampled_from([0.3, 1.0, 5.0, 200.0]))
@settings(max_examples=80)
def test_ir_grid_gives_the_distances_of_every_circle(seed, count, spread):
    """Crowds from overlapping to sparse, cones from a ray to wider than 45 degrees, sensors
    inside circles: the grid broad phase returns the bits of checking every circle."""
    origins, look, cone, owner, circles = crowd(seed, count, spread, 40)
    rays = layout.Rays(origins, look, cone, owner, np.zeros(40, dtype=np.bool_))
    no_walls = gridded(np.zeros((0, 2)), layout.SPANS.new(0), layout.BOXES.new(0), math.inf)
    every, grid = np.empty(40), np.empty(40)
    sense_ir(rays, no_walls, circles, 0.85, every, 1 << 30)
    sense_ir(rays, no_walls, circles, 0.85, grid, 0)
    assert every.tobytes() == grid.tobytes()


@pytest.mark.parametrize("block", [3, 8, 1024])
def test_blocks_hand_out_each_generators_own_sequence(block):
    """Taken in blocks (across refills, rows consumed unevenly), every row's values are its
    generator's standard normals one draw at a time."""
    blocks = NormalBlocks([np.random.default_rng(s) for s in (1, 2)], block=block)
    single = [np.random.default_rng(s) for s in (1, 2)]
    pattern = np.random.default_rng(0).random((50, 2)) < 0.6
    for takes in pattern:
        blocks.reserve(1)
        for row, taking in enumerate(takes):
            if taking:
                assert blocks.values[row, blocks.used[row]] == single[row].normal(0.0, 1.0)
                blocks.used[row] += 1
    even = NormalBlocks([np.random.default_rng(3)], block=block)
    reference = np.random.default_rng(3)
    for _ in range(20):
        assert np.array_equal(even.take(2)[0], reference.normal(0.0, 1.0, size=2))


def test_each_robot_reads_its_own_sensors_in_mixed_and_uniform_fleets():
    """Readings are views into the step's arrays: for robots with different sensor sets (a slice
    per robot) and for a crowd of robots all alike (rows), each robot's views hold its own
    sensors' values, as the robot alone in the world reads them (IR aside: the others are in view)."""
    from bots.ctbot import CTBOT
    from bots.readings import ROWS_FROM
    from sim.world import World
    from sim.world.files import load_world

    blind = CTBOT.with_changes(name="blind", ir=(), light=CTBOT.light[:1], border=())
    spec = load_world("holes_lights")  # lamps and holes: each robot's light and floor readings its own
    for fleet in ((CTBOT, blind, CTBOT), (CTBOT,) * ROWS_FROM):
        seen = set()
        starts = [(0.3 + 0.45 * (k % 6), 0.3 + 0.45 * (k // 6), 0.5 * k) for k in range(len(fleet))]
        world = World(spec, floor_cell=0.01)
        for robot, start in zip(fleet, starts):
            world.add_robot(robot, start)
        for mine, robot, start in zip(world.read_all(), fleet, starts):
            single = World(spec, floor_cell=0.01)
            single.add_robot(robot, start)
            own = single.read_all()[0]
            for kind in ("line", "border", "light"):
                assert getattr(mine, kind).tolist() == getattr(own, kind).tolist() and len(getattr(mine, kind)) == len(getattr(robot, kind))
            assert len(mine.ir_raw) == len(robot.ir) and len(mine.ir_distance) == len(robot.ir)
            seen.add((tuple(mine.light.tolist()), tuple(mine.border.tolist())))
        assert len(seen) >= 2  # the robots read different values: a mix-up would show


def test_a_crowd_of_noisy_sensors_draws_shorter_blocks():
    """Memory stays bounded for thousands of noisy sensors; each still gets its own sequence."""
    from sim.world.noise import HELD, MIN_BLOCK

    blocks = NormalBlocks([np.random.default_rng(s) for s in range(5000)])
    assert MIN_BLOCK <= blocks.values.shape[1] and blocks.values.size <= max(HELD, 5000 * MIN_BLOCK)
    reference = np.random.default_rng(4999)
    for _ in range(3 * blocks.values.shape[1]):
        assert blocks.take(1)[4999, 0] == reference.normal(0.0, 1.0)
