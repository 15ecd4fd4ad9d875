"""`World.read_all` gives one `SensorFrame` a step: the step's own arrays of every robot, and each
robot's `Readings` as views into them, built once when first asked for."""

from __future__ import annotations

import numpy as np
import pytest

from bots.ctbot import CTBOT
from bots.readings import ROWS_FROM, Readings, SensorFrame
from sim.world import World
from sim.world.files import load_world

BLIND = CTBOT.with_changes(name="blind", ir=(), light=CTBOT.light[:1], border=())


def _world(fleet) -> World:
    world = World(load_world("holes_lights"), floor_cell=0.01)
    for k, robot in enumerate(fleet):
        world.add_robot(robot, (0.3 + 0.45 * (k % 6), 0.3 + 0.45 * (k // 6), 0.5 * k))
    return world


@pytest.mark.parametrize("fleet", [(CTBOT, BLIND, CTBOT), (CTBOT,) * ROWS_FROM], ids=["mixed", "alike"])
def test_each_robot_s_readings_are_views_into_the_frame_s_arrays(fleet):
    """Robot after robot, its sensors' rows of the frame's arrays: the per-robot slices (a mixed
    fleet) and the rows (ROWS_FROM robots alike) cut the same places."""
    world = _world(fleet)
    world.step(np.full((len(fleet), 2), 120.0))
    frame = world.read_all()
    assert isinstance(frame, SensorFrame) and len(frame) == len(fleet)
    assert list(frame) == frame.robots() and frame[1] is frame.robots()[1]
    for kind, whole in ((name, frame.arrays[name]) for name in ("ir_raw", "ir_distance", "light")):
        joined = np.concatenate([getattr(r, kind) for r in frame])
        assert np.array_equal(joined, whole, equal_nan=True), kind
        assert all(np.shares_memory(getattr(r, kind), whole) for r in frame if len(getattr(r, kind))), kind
    floors = np.concatenate([np.concatenate((r.line, r.border)) for r in frame])
    assert floors.tolist() == frame.arrays["floor"].tolist()
    for r, robot, tally in zip(frame, fleet, frame.tallies):
        assert len(r.ir_raw) == len(robot.ir) and len(r.line) == len(robot.line) and len(r.border) == len(robot.border)
        assert r.encoder_ticks.tolist() == tally[:2].tolist() and r.mouse_counts.tolist() == tally[2:].tolist()
        assert r.time == frame.time == world.time


def test_readings_kept_stay_as_they_were_read():
    """The arrays are new each step: a controller that keeps last step's readings (or one of their
    arrays) compares it with this step's, not with itself."""
    world = _world((CTBOT,))
    world.step(np.array([[200.0, 80.0]]))
    before = world.read_all()
    kept: Readings = before[0]
    copies = {name: np.copy(getattr(kept, name)) for name in ("encoder_ticks", "mouse_counts", "ir_raw", "ir_distance", "line", "border", "light")}
    tallies = before.tallies.copy()
    for _ in range(20):
        world.step(np.array([[-150.0, 220.0]]))
    after = world.read_all()
    assert not np.array_equal(after.tallies, tallies)  # the world moved on ...
    assert np.array_equal(before.tallies, tallies) and kept.time == before.time  # ... what was read did not
    for name, values in copies.items():
        assert np.array_equal(getattr(kept, name), values, equal_nan=True), name
        assert not np.shares_memory(getattr(after[0], name), getattr(kept, name)), name


def test_a_frame_builds_no_readings_until_asked():
    """Code that works on the arrays (odometry of all robots from `tallies`) costs no object per
    robot; the first robot asked for builds all of them, once."""
    world = _world((CTBOT,) * 3)
    frame = world.read_all()
    assert frame._robots is None
    world.step(np.full((3, 2), 150.0))
    assert np.array_equal(frame.tallies, np.zeros((3, 4)))  # a copy: the world's step does not reach it
    first = frame[2]
    assert frame._robots is not None and frame[2] is first and frame[-1] is first and frame[:2] == frame.robots()[:2]
