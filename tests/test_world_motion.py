"""Issue 3: unobstructed ground truth is the kinematics core's exact arc, holes make robots fall,
bad commands never reach pymunk, and the compiled kernels agree with the numpy reference."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bots.ctbot import CTBOT
from sim.kinematics import (
    integrate_arcs,
    mouse_displacement_from_increment,
    quantize,
    relative_increment,
    wheel_arcs_to_arc,
)
from sim.world import CommandError, World, layout
from sim.world.files import load_world
from sim.world.kernels import motion
from sim.world.kernels.contacts import CLEAR
from sim.world.spec import Hole, Movable, Wall, WorldSpec, box

OPEN = WorldSpec("open", (-5, -5, 5, 5))
START = np.array((0.3, -0.2, 0.4))


def wheel_speeds(spec, commands: np.ndarray, dt: float) -> np.ndarray:
    """Per-step wheel speeds (T, 2) rad/s of the motor model: linear in the command, first-order
    lag exp(-dt/tau) towards it when the motor has a time constant."""
    target = np.clip(commands, -spec.motor.command_max, spec.motor.command_max) / spec.motor.command_max * spec.motor.max_wheel_speed
    if spec.motor.time_constant == 0:
        return target
    keep = math.exp(-dt / spec.motor.time_constant)
    out, current = np.empty_like(target), np.zeros(2)
    for k, t in enumerate(target):
        current = t + (current - t) * keep
        out[k] = current
    return out


def drive(spec, commands: np.ndarray, dt: float) -> tuple[np.ndarray, list]:
    world = World(OPEN, dt=dt)
    world.add_robot(spec, tuple(START))
    poses, readings = [], []
    for c in commands:
        world.step(c[None, :])
        poses.append(world.poses()[0])
        readings.append(world.read_all()[0])
    return np.array(poses), readings


COMMAND_PAIRS = {
    "straight": (200, 200),
    "arc": (255, 120),
    "reverse": (-180, -180),
    "reverse arc": (-90, -250),
    "spin": (-255, 255),
    "one wheel": (0, 150),
}


@pytest.mark.parametrize("name", COMMAND_PAIRS)
def test_unobstructed_ground_truth_is_the_exact_arc(name):
    """Free driving lands on `integrate_arcs` of the motor model's wheel arcs to < 1e-9 m (and
    rad) after every one of 600 steps, for straight, arc, reverse, spin and one-wheel commands."""
    dt = 0.01
    commands = np.tile(np.array(COMMAND_PAIRS[name], dtype=float), (600, 1))
    poses, _ = drive(CTBOT, commands, dt)
    arcs = wheel_speeds(CTBOT, commands, dt) * dt * CTBOT.wheel_radius
    s, alpha = wheel_arcs_to_arc(arcs[:, 0], arcs[:, 1], CTBOT.track_width)
    exact = integrate_arcs(START, s, alpha)
    assert np.abs(poses[:, :2] - exact[:, :2]).max() < 1e-9
    assert np.abs(poses[:, 2] - exact[:, 2]).max() < 1e-9


def test_ground_truth_with_motor_lag_follows_the_actual_wheel_speeds():
    """With a motor time constant (50 ms) and changing commands, ground truth is the exact arc of
    the lagged per-step wheel speeds (< 1e-9 m), and the encoders count exactly those speeds."""
    spec = CTBOT.with_changes(motor={"time_constant": 0.05})
    dt = 0.01
    commands = np.concatenate([np.tile(c, (n, 1)) for c, n in (((255.0, 255.0), 60), ((-100.0, 200.0), 80), ((0.0, 0.0), 40), ((-255.0, -60.0), 70))])
    poses, readings = drive(spec, commands, dt)
    speeds = wheel_speeds(spec, commands, dt)
    assert not np.allclose(speeds, wheel_speeds(CTBOT, commands, dt)), "the lag must matter"
    arcs = speeds * dt * spec.wheel_radius
    s, alpha = wheel_arcs_to_arc(arcs[:, 0], arcs[:, 1], spec.track_width)
    exact = integrate_arcs(START, s, alpha)
    assert np.abs(poses - exact).max() < 1e-9
    ticks = np.cumsum([r.encoder_ticks for r in readings], axis=0)
    rotation = np.cumsum(speeds * dt, axis=0) * spec.encoders.ticks_per_rev / (2 * math.pi)
    assert np.all(np.abs(ticks - rotation) < 1.0 + 1e-9)


def test_mouse_reads_the_exact_arc_under_its_mount():
    """Unobstructed, the mouse counts sum to the exact ground motion under the mount (seed 002:
    forward s - alpha*m_y, left alpha*m_x per step) to within one count."""
    dt = 0.01
    commands = np.tile((255.0, 100.0), (300, 1))
    _, readings = drive(CTBOT, commands, dt)
    arcs = wheel_speeds(CTBOT, commands, dt) * dt * CTBOT.wheel_radius
    s, alpha = wheel_arcs_to_arc(arcs[:, 0], arcs[:, 1], CTBOT.track_width)
    mx, my = CTBOT.mouse.mount
    expected = np.array((np.sum(s - alpha * my), np.sum(alpha * mx))) * CTBOT.mouse.dpi / 0.0254
    counts = np.sum([r.mouse_counts for r in readings], axis=0)
    assert np.all(np.abs(counts - expected) <= 1.0), (counts, expected)


def test_a_robot_driving_over_a_hole_falls_and_stays():
    """In worlds/holes_lights.toml the robot drives straight into the slot: it falls (fallen True),
    stops moving, its mouse reads 0, its encoders keep counting; its border sensors saw 1023 first."""
    world = World(load_world("holes_lights"), dt=0.01)
    robot = world.add_robot(CTBOT)
    saw_hole = False
    for _ in range(500):
        r = world.read_all()[0]
        saw_hole |= bool(np.all(r.border == 1023)) and not robot.fallen
        world.step(np.array([[200.0, 200.0]]))
        if robot.fallen:
            break
    assert robot.fallen and saw_hole
    x, _, _ = world.poses()[0]
    assert 1.3 - CTBOT.body_radius < x < 1.55, "it fell at the slot"
    where = world.poses()[0]
    for _ in range(50):
        world.step(np.array([[200.0, -200.0]]))
        r = world.read_all()[0]
        assert np.all(r.mouse_counts == 0)
        assert np.all(np.abs(r.encoder_ticks) >= 1)
    assert np.array_equal(world.poses()[0], where)


def test_a_wheel_over_a_small_hole_is_enough_to_fall():
    """A hole under the left wheel only (a small WorldSpec) makes the robot fall; one beside it
    does not."""
    hole = Hole(box(0.2, 0.04, 0.3, 0.2))
    world = World(WorldSpec("hole", (-1, -1, 1, 1), holes=(hole,)), dt=0.01)
    falls = world.add_robot(CTBOT, (0.1, 0.0, 0.0))
    passes = world.add_robot(CTBOT, (0.1, -0.4, 0.0))
    for _ in range(60):
        world.step(np.full((2, 2), 255.0))
    assert falls.fallen and not passes.fallen
    assert 0.2 - 0.0046 <= world.poses()[0, 0] <= 0.2 + 0.0046, "it stops where the wheel met the hole"


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_commands_are_refused_before_pymunk(bad):
    """NaN or infinite commands raise CommandError naming the robot and the step; the world is
    untouched (poses, time, readings, pymunk bodies) and keeps running with good commands."""
    world = World(OPEN, dt=0.01)
    world.add_robot(CTBOT, (0.0, 0.0, 0.0))
    world.add_robot(CTBOT, (1.0, 0.0, 0.0), name="second")
    for _ in range(5):
        world.step(np.full((2, 2), 100.0))
    poses, time, readings = world.poses(), world.time, world.read_all()
    bodies = [(tuple(r.body.position), r.body.angle, tuple(r.body.velocity), tuple(r.body.force)) for r in world.robots]
    with pytest.raises(CommandError, match=r"second.*step 5"):
        world.step(np.array([[100.0, 100.0], [bad, 100.0]]))
    assert np.array_equal(world.poses(), poses) and world.time == time and world.steps == 5
    assert [(tuple(r.body.position), r.body.angle, tuple(r.body.velocity), tuple(r.body.force)) for r in world.robots] == bodies
    after = world.read_all()
    assert all(np.array_equal(a.encoder_ticks, b.encoder_ticks) and np.array_equal(a.mouse_counts, b.mouse_counts) for a, b in zip(after, readings))
    with pytest.raises(CommandError, match="shape"):
        world.step(np.zeros((1, 2)))
    world.step(np.full((2, 2), 100.0))
    assert world.steps == 6


def test_a_refused_step_draws_no_noise():
    """A step refused for a non-finite command draws nothing from the encoders' generators: a
    noisy world that met one runs on exactly as one that never did."""
    noisy = CTBOT.with_changes(encoders={"slip_std": 0.05, "tick_noise": 0.2})
    worlds = [World(OPEN, dt=0.01, seed=3) for _ in range(2)]
    for world in worlds:
        world.add_robot(noisy, (0.0, 0.0, 0.0))
    with pytest.raises(CommandError):
        worlds[0].step(np.array([[math.nan, 100.0]]))
    ticks = [[], []]
    for _ in range(20):
        for world, seen in zip(worlds, ticks):
            world.step(np.array([[120.0, 100.0]]))
            seen.append(world.read_all()[0].encoder_ticks)
    assert np.array_equal(ticks[0], ticks[1])


def test_measure_kernel_agrees_with_the_reference_mouse():
    """`kernels.motion.measure` gives the counts of `mouse_displacement_from_increment` + `quantize`
    (carry included) for random true motions, including bent (non-arc) ones."""
    rng = np.random.default_rng(3)
    n = 200
    before = np.column_stack((rng.uniform(-1, 1, (n, 2)), rng.uniform(-4, 4, n)))
    after = before + np.column_stack((rng.normal(0, 0.005, (n, 2)), rng.normal(0, 0.1, n)))
    mount = rng.uniform(-0.05, 0.05, (n, 2))
    cpm = np.full(n, 400 / 0.0254)
    carry = rng.uniform(0, 1, (n, 2))
    robots, state, tallies = layout.ROBOTS.new(n), layout.STATE.new(n), layout.TALLIES.new(n)
    robots["mount"], robots["counts_per_metre"], robots["max_step"] = mount, cpm, np.inf
    state["mouse_carry"] = carry
    no_holes = layout.Floor(np.zeros((1, 1), np.float32), np.full((1, 1), np.nan, np.float32), np.zeros((1, 1), dtype=bool), np.array((-10.0, -10.0)), 100.0, 0.0,
                            False, 0.0)
    motion.measure(before, after, robots, state, tallies, no_holes)
    counts, mouse_carry = tallies["counts"], state["mouse_carry"]
    displacement = mouse_displacement_from_increment(relative_increment(before, after), mount)
    ref_counts, ref_carry = quantize(displacement * cpm[:, None], carry)
    assert np.array_equal(counts, ref_counts)
    assert np.allclose(mouse_carry, ref_carry, atol=1e-9)


def test_drive_kernel_agrees_with_the_reference_arc():
    """`kernels.motion.drive` moves each robot by the chord and heading change of the reference
    exact arc (`integrate_arcs` of one step) and counts ticks like `quantize`."""
    rng = np.random.default_rng(4)
    n = 100
    commands = rng.uniform(-300, 300, (n, 2))
    commands[:5] = ((255, 255), (-255, 255), (0, 0), (100, 100 + 1e-12), (-40, -40))
    pose = np.column_stack((rng.uniform(-1, 1, (n, 2)), rng.uniform(-4, 4, n)))
    dt, radius, track, wmax = 0.01, CTBOT.wheel_radius, CTBOT.track_width, CTBOT.motor.max_wheel_speed
    carry = rng.uniform(0, 1, (n, 2))
    robots, state, tallies, world = layout.ROBOTS.new(n), layout.STATE.new(n), layout.TALLIES.new(n), layout.WORLD.new(1)
    robots["command_max"], robots["max_speed"], robots["lag"], robots["max_change"] = 255.0, wmax, 1.0, np.inf
    robots["ticks_per_rad"], robots["real_radius"], robots["track"] = 60 / (2 * math.pi), radius, track
    state["tick_carry"], world["dt"] = carry, dt
    motion.drive(commands, robots, state, tallies, pose, world)
    move, alpha, ticks = state["move"], state["alpha"], tallies["ticks"]
    speed = np.clip(commands, -255, 255) / 255 * wmax
    s, a = wheel_arcs_to_arc(speed[:, 0] * dt * radius, speed[:, 1] * dt * radius, track)
    end = integrate_arcs(pose, s[None], a[None])[0]
    assert np.abs(pose[:, :2] + move - end[:, :2]).max() < 1e-15
    assert np.abs(alpha - a).max() < 1e-15
    ref_ticks, _ = quantize(speed * dt * 60 / (2 * math.pi), carry)
    assert np.array_equal(ticks, ref_ticks)


def _quiet_trace(quiet: bool, steps: int = 3000) -> tuple[np.ndarray, np.ndarray, np.ndarray, int, int]:
    """A c't-Bot in the maze driving straight into walls and backing off in turns (contacts and
    free stretches): poses, tallies and IR values of every step, collisions and quiet steps;
    `quiet=False` makes pymunk take every step."""
    world = World(load_world("maze"))
    world.add_robot(CTBOT)
    world.poses()  # (builds the step's arrays)
    if not quiet:
        world._world["quiet_after"] = -1
    poses, tallies, ir, quiet_steps = [], [], [], 0
    for k in range(steps):
        frame = world.read_all()
        tallies.append(frame.tallies.copy())
        ir.append(frame.arrays["ir_raw"].copy())
        world.step(np.array([[200.0, 200.0]]) if (k // 300) % 2 == 0 else np.array([[-150.0, 120.0]]))
        quiet_steps += world._world[0]["streak"] > world._world[0]["quiet_after"] >= 0
        poses.append(world.poses())
    return np.array(poses), np.array(tallies), np.array(ir), world.robots[0].collisions, quiet_steps


def test_quiet_steps_move_the_robot_as_pymunk_does():
    """Steps that begin with the robot clear of every wall (and pymunk's contact memory empty) skip
    pymunk: poses bit for bit, ticks, mouse counts, IR values and collisions equal those of a world
    where pymunk takes every step, over a drive with both kinds of step."""
    poses, tallies, ir, collisions, quiet_steps = _quiet_trace(True)
    pymunk_poses, pymunk_tallies, pymunk_ir, pymunk_collisions, none = _quiet_trace(False)
    assert none == 0 and 500 < quiet_steps < 2500 and collisions > 5  # both kinds of step happened
    np.testing.assert_array_equal(poses, pymunk_poses)
    np.testing.assert_array_equal(tallies, pymunk_tallies)
    np.testing.assert_array_equal(ir, pymunk_ir)
    assert collisions == pymunk_collisions


def test_quiet_steps_only_for_one_round_robot_and_nothing_else_that_moves():
    """With a second robot or a movable can, pymunk takes every step (its broad phase orders the
    contacts of several bodies by their history); a robot touching a wall is never quiet."""
    crowded = World(OPEN)
    crowded.add_robot(CTBOT, (0.0, 0.0, 0.0))
    crowded.add_robot(CTBOT, (1.0, 0.0, 0.0))
    with_can = World(WorldSpec("can", (-5, -5, 5, 5), movables=(Movable((1.0, 1.0), 0.015, 0.05),)))
    with_can.add_robot(CTBOT, (0.0, 0.0, 0.0))
    for world in (crowded, with_can):
        world.step(np.zeros((len(world.robots), 2)))
        assert world._world[0]["quiet_after"] == -1
    walled = World(WorldSpec("walled", (-1, -1, 1, 1), walls=(Wall(box(0.1, -0.5, 0.2, 0.5)),)))
    walled.add_robot(CTBOT, (0.1 - CTBOT.body_radius - 0.5 * CLEAR, 0.0, 0.0))
    for _ in range(10):
        walled.step(np.zeros((1, 2)))
    assert walled._world[0]["quiet_after"] == walled.space.collision_persistence and walled._world[0]["streak"] == 0
