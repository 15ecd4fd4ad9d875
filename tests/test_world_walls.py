"""Issue 3: walls and other robots stop a robot (no tunnelling, < 1 mm overlap at any speed and dt),
the encoders keep counting while it is blocked, and the mouse reads the body's true motion."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from bots.ctbot import CTBOT
from sim.world import World
from sim.world.spec import Wall, WorldSpec

R = CTBOT.body_radius
FULL = 255.0
WHEEL_SPEED = CTBOT.motor.max_wheel_speed  # rad/s at full command
SPEED = WHEEL_SPEED * CTBOT.wheel_radius  # m/s
TICKS_PER_RAD = CTBOT.encoders.ticks_per_rev / (2 * math.pi)
COUNTS_PER_M = CTBOT.mouse.dpi / 0.0254
MAX_OVERLAP = 0.001  # m


def rotated_box(cx: float, cy: float, half_length: float, half_width: float, angle: float) -> tuple:
    """Counter-clockwise corners of a box centred at (cx, cy), its long side along `angle`."""
    c, s = math.cos(angle), math.sin(angle)
    corners = ((-half_length, -half_width), (half_length, -half_width), (half_length, half_width), (-half_length, half_width))
    return tuple((cx + c * x - s * y, cy + s * x + c * y) for x, y in corners)


def signed_distance(point: np.ndarray, vertices: tuple) -> float:
    """Signed distance (m) from a point to a convex counter-clockwise polygon: < 0 inside."""
    v = np.asarray(vertices, dtype=float)
    p = np.asarray(point[:2], dtype=float)
    edges = np.roll(v, -1, axis=0) - v
    normals = np.stack((edges[:, 1], -edges[:, 0]), axis=1) / np.linalg.norm(edges, axis=1)[:, None]
    plane = np.einsum("ij,ij->i", p - v, normals)
    if np.all(plane <= 0):
        return float(plane.max())
    t = np.clip(np.einsum("ij,ij->i", p - v, edges) / np.einsum("ij,ij->i", edges, edges), 0, 1)
    return float(np.min(np.linalg.norm(p - (v + t[:, None] * edges), axis=1)))


def penetration(pose: np.ndarray, walls: tuple) -> float:
    """How deep (m) the robot's circle reaches into the deepest wall (negative: clear of all)."""
    return max(R - signed_distance(pose, w.vertices) for w in walls)


@settings(max_examples=40)
@given(
    wall_angle=st.floats(-math.pi, math.pi),
    approach=st.floats(-1.3, 1.3),
    command=st.floats(60.0, FULL) | st.just(FULL),
    dt=st.floats(0.001, 0.05) | st.just(0.05),
    gap=st.floats(0.0, 0.05),
)
def test_no_robot_sinks_more_than_a_millimetre_into_a_wall(wall_angle, approach, command, dt, gap):
    """Driving straight at a wall (any wall direction, approach angle up to 75 deg off its normal,
    any speed up to full, dt 1-50 ms) never puts the body more than 1 mm into it, checked every
    step from the pose, the body radius and the wall polygon."""
    normal = wall_angle + math.pi / 2  # the wall's face looks back along -normal towards the robot
    wall = Wall(rotated_box(0.3 * math.cos(normal), 0.3 * math.sin(normal), 1.0, 0.01, wall_angle))
    spec = WorldSpec("wall", (-1.5, -1.5, 1.5, 1.5), walls=(wall,))
    world = World(spec, dt=dt)
    # the wall's face is 0.29 m from the origin; the robot's centre on the normal, `gap` from touching
    offset = 0.29 - R - gap
    start = (offset * math.cos(normal), offset * math.sin(normal), normal + approach)
    world.add_robot(CTBOT, start)
    speed = command / FULL * SPEED
    steps = math.ceil((gap / (speed * math.cos(approach)) + 0.25) / dt)
    deepest = -math.inf
    for _ in range(steps):
        world.step(np.array([[command, command]]))
        deepest = max(deepest, penetration(world.poses()[0], (wall,)))
    assert deepest <= MAX_OVERLAP, f"{deepest * 1000:.3f} mm into the wall"
    assert deepest > -1e-4, "the robot should have reached the wall"


def test_into_a_corner_at_full_speed_stays_out_of_both_walls():
    """Sliding along one wall into another (a corner) also stays within 1 mm of both, at 10 and 50 ms."""
    walls = (Wall(((0.5, -1.0), (0.6, -1.0), (0.6, 0.6), (0.5, 0.6))), Wall(((-1.0, 0.5), (0.6, 0.5), (0.6, 0.6), (-1.0, 0.6))))
    for dt in (0.01, 0.05):
        for heading in (0.3, 0.8, 1.2):
            world = World(WorldSpec("corner", (-1.5, -1.5, 1.5, 1.5), walls=walls), dt=dt)
            world.add_robot(CTBOT, (0.0, 0.0, heading))
            deepest = -math.inf
            for _ in range(int(5.0 / dt)):
                world.step(np.array([[FULL, FULL]]))
                deepest = max(deepest, penetration(world.poses()[0], walls))
            x, y, _ = world.poses()[0]
            assert deepest <= MAX_OVERLAP, f"dt {dt}, heading {heading}: {deepest * 1000:.3f} mm"
            assert x > 0.5 - R - 0.002 and y > 0.5 - R - 0.002, "the robot ends up in the corner"


def blocked_world(heading: float, dt: float = 0.01) -> World:
    """A robot already touching a wall at x = 0.5 (face), heading `heading` against it."""
    wall = Wall(((0.5, -2.0), (0.6, -2.0), (0.6, 2.0), (0.5, 2.0)))
    world = World(WorldSpec("wall", (-2.5, -2.5, 2.5, 2.5), walls=(wall,)), dt=dt)
    world.add_robot(CTBOT, (0.5 - R - 0.0005, 0.0, heading))
    return world


def test_head_on_the_encoders_count_the_wheels_and_the_mouse_reads_nothing():
    """Pushing head-on against a wall at full speed: the pose does not change, the encoders count
    the wheel rotation (1.51 ticks per 10 ms step, summed exactly to within one tick), the mouse
    reads (nearly) zero."""
    world = blocked_world(0.0)
    for _ in range(20):
        world.step(np.array([[FULL, FULL]]))
        world.read_all()
    before = world.poses()[0]
    ticks, counts = np.zeros(2, dtype=int), np.zeros(2, dtype=int)
    steps = 300
    for _ in range(steps):
        world.step(np.array([[FULL, FULL]]))
        r = world.read_all()[0]
        ticks += r.encoder_ticks
        counts += np.abs(r.mouse_counts)
        assert 1 <= r.encoder_ticks.min() and r.encoder_ticks.max() <= 2
    expected = WHEEL_SPEED * world.dt * TICKS_PER_RAD * steps  # 453 ticks
    assert np.all(np.abs(ticks - expected) <= 1), (ticks, expected)
    assert counts.sum() <= 2, counts  # of 4500 counts had it moved freely
    assert np.abs(world.poses()[0] - before).max() < 1e-4  # contact settling only, 0.1 mm


def test_at_an_angle_the_robot_slides_and_the_mouse_reads_the_slide():
    """Pushing against a wall at 30 deg off its normal, the robot slides along it at v*sin(30 deg);
    the mouse reads that slide in its own frame (forward v sin^2, left v sin cos) to within 1 %,
    and the encoders still count the full wheel rotation."""
    approach = math.radians(30)
    world = blocked_world(approach)
    for _ in range(20):
        world.step(np.array([[FULL, FULL]]))
        world.read_all()
    y0 = world.poses()[0, 1]
    steps = 100
    counts, ticks = np.zeros(2), np.zeros(2)
    for _ in range(steps):
        world.step(np.array([[FULL, FULL]]))
        r = world.read_all()[0]
        counts += r.mouse_counts
        ticks += r.encoder_ticks
    slide = SPEED * math.sin(approach) * steps * world.dt  # along +y, the wall's tangent
    assert abs((world.poses()[0, 1] - y0) - slide) < 0.01 * slide
    expected = np.array((slide * math.sin(approach), slide * math.cos(approach))) * COUNTS_PER_M
    assert np.all(np.abs(counts - expected) <= 0.01 * np.abs(expected) + 2), (counts, expected)
    assert np.all(np.abs(ticks - WHEEL_SPEED * world.dt * TICKS_PER_RAD * steps) <= 1)


def test_turning_in_place_against_a_wall_still_turns():
    """A blocked robot can still spin (c't-Sim: heading is committed against a wall)."""
    world = blocked_world(0.0)
    world.step(np.array([[-FULL, FULL]]))
    alpha = 2 * SPEED * world.dt / CTBOT.track_width
    assert abs(world.poses()[0, 2] - alpha) < 1e-12


def test_two_robots_head_on_stop_without_overlapping_and_count_the_collision():
    """Two robots driving at each other at full speed stop touching (overlap < 1 mm at dt 10 and
    50 ms); both count one collision; their encoders keep counting."""
    for dt in (0.01, 0.05):
        world = World(WorldSpec("open", (-2, -2, 2, 2)), dt=dt)
        a = world.add_robot(CTBOT, (-0.3, 0.0, 0.0))
        b = world.add_robot(CTBOT, (0.3, 0.01, math.pi))
        worst = -math.inf
        for _ in range(int(2.0 / dt)):
            world.step(np.full((2, 2), FULL))
            p = world.poses()
            worst = max(worst, 2 * R - math.dist(p[0, :2], p[1, :2]))
        readings = world.read_all()
        assert worst <= MAX_OVERLAP, f"dt {dt}: overlap {worst * 1000:.3f} mm"
        assert worst > -1e-3, "they should have met"
        assert a.collisions >= 1 and b.collisions >= 1
        assert all(r.encoder_ticks.min() >= 1 for r in readings)


def test_a_robot_is_an_obstacle_to_another_at_any_angle():
    """A robot driving into a standing robot from several directions never overlaps it by more than
    1 mm; the moving robot's contact is counted."""
    for angle in np.linspace(0, 2 * math.pi, 7, endpoint=False):
        world = World(WorldSpec("open", (-2, -2, 2, 2)), dt=0.02)
        world.add_robot(CTBOT, (0.0, 0.0, 0.0))
        mover = world.add_robot(CTBOT, (0.4 * math.cos(angle), 0.4 * math.sin(angle), angle + math.pi + 0.1))
        worst = -math.inf
        for _ in range(100):
            world.step(np.array([[0.0, 0.0], [FULL, FULL]]))
            p = world.poses()
            worst = max(worst, 2 * R - math.dist(p[0, :2], p[1, :2]))
        assert -1e-3 < worst <= MAX_OVERLAP, f"angle {angle:.2f}: {worst * 1000:.3f} mm"
        assert mover.collisions >= 1


def test_the_stop_rule_refuses_a_move_into_a_wall_but_not_the_turn():
    """contact 'stop' (c't-Sim's rule): 60.5 mm from a wall, a full-speed step (4.5 mm) at 45
    degrees to it would bring the body within its radius, so the robot does not move at all (no
    slide along the wall); it counts one collision, and it still turns on the spot. A 'slide'
    robot in the same place slides along the wall."""
    wall = Wall(((0.0605, -1.0), (0.2, -1.0), (0.2, 1.0), (0.0605, 1.0)))
    results = {}
    for rule in ("stop", "slide"):
        world = World(WorldSpec("w", (-2, -2, 2, 2), walls=(wall,)))
        robot = world.add_robot(CTBOT.with_changes(contact=rule), (0.0, 0.0, math.pi / 4))
        for _ in range(5):
            world.step(np.array([[FULL, FULL]]))
        results[rule] = robot.pose.copy(), robot.collisions
    (stopped, collisions), (slid, _) = results["stop"], results["slide"]
    assert stopped[0] == 0.0 and stopped[1] == 0.0 and collisions == 1
    assert slid[1] > 0.01  # along the wall
    world = World(WorldSpec("w", (-2, -2, 2, 2), walls=(wall,)))
    robot = world.add_robot(CTBOT.with_changes(contact="stop"), (0.0, 0.0, math.pi / 4))
    world.step(np.array([[-FULL, FULL]]))
    assert robot.pose[2] > math.pi / 4 and robot.pose[0] == 0.0  # a turn in place is never refused


def test_the_stop_rule_keeps_a_robot_clear_of_another():
    """Two 'stop' robots driving at each other mouth to mouth meet by c't-Sim's rule alone: each
    one's 60 mm sphere meets the other's cheek boxes 106.66 mm between the centres, inside their
    circles' 120 mm (c't-Sim stops two firmware bots 106.96 mm apart; tests/test_ctsim_contact.py
    holds the rule), and a step is refused once it would bring its bot within that, so at full
    speed they end less than a step's travel each short of it, never past it."""
    world = World(WorldSpec("w", (-2, -2, 2, 2)))
    spec = CTBOT.with_changes(contact="stop")
    a, b = world.add_robot(spec, (-0.2, 0.0, 0.0)), world.add_robot(spec, (0.2, 0.0, math.pi))
    for _ in range(100):
        world.step(np.array([[FULL, FULL], [FULL, FULL]]))
    gap = math.hypot(*(a.pose[:2] - b.pose[:2]))
    cheeks, step = 0.10666, SPEED * world.dt
    assert cheeks - 2 * step < gap <= cheeks
