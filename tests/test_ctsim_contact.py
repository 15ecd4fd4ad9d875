"""Issue 12, part 1: border sensors, holes and start slots as c't-Sim has them.

Border (and line) sensors average c't-Sim's "+" of rays (`World.sensGroundReflectionCross`);
a robot stops at a hole by c't-Sim's ground-contact rule (`MasterSimulator`, skid at the new pose,
wheels at the old position); `ctsim check` says how many robots a world takes. The c't-Sim world
files come from ../shared/ctsim and their tests skip where it is absent.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from printed import places
from shared_data import PARCOURS
from shared_data import needs_parcours as needs_shared

from bots.ctbot import CTBOT
from sim.bridge.session import as_in_ctsim
from sim.cli.entry import main
from sim.world import World
from sim.world.files import load_world, room_warning
from sim.world.spec import Hole, WorldSpec, box

FLOOR = np.float32(1.0) - np.float32(0x60 / 255)  # what the normal floor #606060 swallows, float32 as in c't-Sim
BORDER_X = CTBOT.border[0].position[0]  # 38.4 mm ahead of the axle
FAN_REACH = [0.014 * math.tan(math.radians(a)) for a in (40, 20)]  # 11.7 and 5.1 mm from 14 mm up
STEP = 255 / 255 * CTBOT.max_wheel_surface_speed * 0.01  # the farthest a c't-Bot moves in a 10 ms step (m)
CELL = 0.002  # the floor raster: a hole edge is placed to within one cell


def fan_value(holes: int) -> int:
    """c't-Sim's value of one fan of five rays of which `holes` see a hole, the rest the floor."""
    swallowed = np.float32(0.0)
    for k in range(5):
        swallowed += np.float32(1.0) if k < holes else FLOOR
    return int(swallowed * np.float32(1023) / np.float32(5))


@pytest.mark.parametrize(
    ("edge_mm", "along"),
    [
        (BORDER_X * 1000 + 13, 0),  # beyond the farthest ray: all floor
        (BORDER_X * 1000 + 8, 1),  # only the ray 40 degrees forward sees the hole
        (BORDER_X * 1000 + 3, 2),  # the rays 20 and 40 degrees forward
        (BORDER_X * 1000 - 3, 3),  # and the vertical one
        (BORDER_X * 1000 - 8, 4),  # all but the ray 40 degrees back
        (BORDER_X * 1000 - 13, 5),  # all
    ],
)
def test_border_sensors_average_a_cross_of_rays(edge_mm, along):
    """A hole whose edge runs across the heading at `edge_mm` ahead of the axle: the fan along the
    heading sees it with `along` of its rays (they meet the floor 0, ±5.1 and ±11.7 mm from the
    mount point); the fan across the heading sees it with all five rays once the mount point is
    over it, with none before. The reading is the mean of the two truncated fans, truncated."""
    world = World(WorldSpec("edge", (-1, -1, 1, 1), holes=(Hole(box(edge_mm / 1000, -0.5, 0.5, 0.5)),)))
    world.add_robot(CTBOT, (0.0, 0.0, 0.0))
    across = 5 if edge_mm < BORDER_X * 1000 else 0
    expected = (fan_value(along) + fan_value(across)) // 2
    assert list(world.read_all()[0].border) == [expected, expected]


def test_the_cross_reaches_12_mm_sideways_and_follows_the_heading():
    """A hole beside the robot, its edge 10 mm to the left of the left border sensor: only the ray
    40 degrees to the left (11.7 mm) sees it (the floor raster places an edge to within a 2 mm
    cell, so the edge keeps more than a millimetre from every ray); turned by 90 degrees the same
    fan reaches it along the other axis. The reach is c't-Sim's 14 mm height times tan 40°."""
    assert FAN_REACH[0] == pytest.approx(0.0117, abs=places(4))
    _, y = CTBOT.border[0].position
    hole = Hole(box(-0.5, y + 0.010, 0.5, 0.5))
    world = World(WorldSpec("side", (-1, -1, 1, 1), holes=(hole,)))
    world.add_robot(CTBOT, (0.0, 0.0, 0.0))
    left, right = world.read_all()[0].border
    assert left == (fan_value(1) + fan_value(0)) // 2 and right == fan_value(0)
    # the same geometry turned a quarter: the robot faces +y, the hole lies at x < -(y + 10 mm)
    turned = World(WorldSpec("side", (-1, -1, 1, 1), holes=(Hole(box(-0.5, -0.5, -(y + 0.010), 0.5)),)))
    turned.add_robot(CTBOT, (0.0, 0.0, math.pi / 2))
    assert list(turned.read_all()[0].border) == [left, right]


def drive(world: World, commands, steps: int) -> None:
    for _ in range(steps):
        world.step(np.array([commands], dtype=np.float64))


def test_a_skid_over_a_hole_stops_the_robot_and_it_drives_off_again():
    """Reversing towards a hole, the robot stops where its skid (54 mm behind the axle) would next
    be over it, and says so (fallen) while it keeps trying; driving forward it leaves: c't-Sim
    checks the skid at the new position, so it never gets over the hole."""
    edge = -0.2
    world = World(WorldSpec("hole behind", (-1, -1, 1, 1), holes=(Hole(box(-0.5, -0.5, edge, 0.5)),)))
    robot = world.add_robot(CTBOT, (0.0, 0.0, 0.0))
    drive(world, (-255, -255), 150)
    x = world.poses()[0, 0]
    skid = x + CTBOT.skid[0]
    assert robot.fallen
    assert edge - CELL <= skid <= edge + STEP + CELL, "the skid stops at the edge, not beyond it"
    drive(world, (-255, -255), 20)
    assert world.poses()[0, 0] == x and robot.fallen  # every further move backwards is refused
    drive(world, (255, 255), 20)
    assert not robot.fallen and world.poses()[0, 0] > x + 0.05


def test_wheels_over_a_hole_keep_the_robot_there():
    """Driving forward at a hole, the wheels are checked at the old position (c't-Sim): the robot
    moves one step past the point where its axle meets the edge and then every move, forwards,
    backwards or turning, is refused: it stays there, falling, with its encoders still counting."""
    edge = 0.2
    world = World(WorldSpec("hole ahead", (-1, -1, 1, 1), holes=(Hole(box(edge, -0.5, 0.5, 0.5)),)))
    robot = world.add_robot(CTBOT, (0.0, 0.0, 0.0))
    drive(world, (255, 255), 150)
    where = world.poses()[0]
    assert robot.fallen and edge - CELL <= where[0] <= edge + STEP + CELL
    for commands in ((-255, -255), (255, -255), (-255, 255)):
        drive(world, commands, 20)
        assert np.array_equal(world.poses()[0], where) and robot.fallen
        r = world.read_all()[0]
        assert np.all(r.mouse_counts == 0) and np.all(np.abs(r.encoder_ticks) >= 1)


@needs_shared
def test_ctsim_world_hole_and_map_edge():
    """In c't-Sim's testparcours2.xml, whose hole row (LLL) spans y 2.88-3.12 m from x = 1.20 m
    with a wall just below it: a robot above it reversing towards it stops with its skid at the
    hole's edge and drives off again."""
    world_spec = load_world(PARCOURS / "testparcours2.xml")
    assert any(np.allclose(np.min(h.vertices, axis=0), (1.2, 2.88)) and np.max(h.vertices, axis=0)[1] == pytest.approx(3.12) for h in world_spec.holes)
    world = World(world_spec)
    robot = world.add_robot(CTBOT, (1.32, 3.28, math.pi / 2))  # facing +y: the skid points at the hole
    drive(world, (-200, -200), 200)
    skid_y = world.poses()[0, 1] + CTBOT.skid[0]
    assert robot.fallen and robot.collisions == 0 and 3.12 - CELL <= skid_y <= 3.12 + STEP + CELL
    drive(world, (200, 200), 20)
    assert not robot.fallen


def test_off_the_map_is_a_hole_where_the_world_says_so():
    """c't-Sim's `Parcours.checkHole` counts everything off the map as a hole (ctsim: a world with
    `outside_is_hole`, as every c't-Sim world loads): reversing towards the map's edge the robot
    stops with its skid at the edge; where the outside is floor it drives on."""
    for outside_is_hole in (True, False):
        world = World(WorldSpec("open edge", (0, 0, 1, 1), outside_is_hole=outside_is_hole))
        robot = world.add_robot(CTBOT, (0.2, 0.5, 0.0))
        drive(world, (-200, -200), 200)
        skid = world.poses()[0, 0] + CTBOT.skid[0]
        assert robot.fallen == outside_is_hole
        assert (-CELL <= skid <= STEP + CELL) if outside_is_hole else skid < -0.5


@needs_shared
def test_check_says_how_many_robots_a_world_takes(capsys):
    """c't-Sim's maze.xml has one start slot: `ctsim check` warns that it takes one robot (two are
    common) and says so in its summary; testline.xml takes two and does not warn."""
    assert main(["check", str(PARCOURS / "maze.xml")]) == 0
    out = capsys.readouterr().out
    assert "warning: room for 1 robot(s) only" in out and out.rstrip().endswith("room for 1 robot(s)")
    assert main(["check", str(PARCOURS / "testline.xml")]) == 0
    out = capsys.readouterr().out
    assert "warning" not in out and out.rstrip().endswith("room for 2 robot(s)")
    assert room_warning(load_world(PARCOURS / "maze.xml"), robots=1) is None


def test_a_c_t_bot_stops_behind_another_at_the_box_round_its_back_part():
    """c't-Sim meets another bot at the boxes round its three Java3D parts (`CtBotShape`), each
    turned with the bot and boxed again in world axes: the middle part behind the mouth reaches
    59.93 mm back, 27.5 mm to either side, so a bot turned 1.19° reaches 59.93 cos 1.19° + 27.5 sin
    1.19° = 60.49 mm back, 0.49 mm past its circle, and the bot driving up behind stops within a
    step before its own 60 mm meet that (c't-Sim stopped two bots driving one behind the other in
    winzig.xml a step apart from the sum of their radii)."""
    turn = math.radians(1.19)
    front_y, bot = 0.3, as_in_ctsim(CTBOT)
    world = World(WorldSpec("open", (-1, -1, 1, 1)))
    world.add_robot(bot, (0.0, front_y, math.pi / 2 + turn))
    world.add_robot(bot, (0.0, 0.0, math.pi / 2))
    for _ in range(400):
        before = world.poses()[1, 1]
        world.step(np.array([(0.0, 0.0), (30.0, 30.0)]))
        step = world.poses()[1, 1] - before
    reach = 0.059932 * math.cos(turn) + 0.0275 * math.sin(turn)
    contact = front_y - reach - 0.06
    y = world.poses()[1, 1]
    assert step == 0.0 and round(reach, 5) == 0.06049
    assert contact - 0.0005 < y < contact  # within the last step (0.3 mm at 30 units) before it, 0.49 mm short of the circles' contact


def test_two_c_t_bots_mouth_to_mouth_stop_where_the_cheeks_boxes_meet_the_other_s_sphere():
    """Mouth to mouth, each bot's 60 mm sphere meets the other's cheek boxes, which reach 53.33 mm
    forward from 27.5 mm beside the axis: at 53.33 + sqrt(60² - 27.5²) = 106.66 mm between the
    centres, inside their circles' 120 mm, which ctsim's own robots keep (c't-Sim: two firmware
    bots driving at each other stopped 106.96 mm apart). Both move in the same step, each against
    where the other stood: a step is refused once it would bring its bot within 106.66 mm of the
    other, so they end less than a step's travel either side of it."""
    bot = as_in_ctsim(CTBOT)
    world = World(WorldSpec("open", (-1, -1, 1, 1)))
    world.add_robot(bot, (-0.2, 0.0, 0.0))
    world.add_robot(bot, (0.2, 0.0, math.pi))
    travel, last = 0.0, 0.0
    for _ in range(1000):
        before = world.poses()[0, 0]
        world.step(np.array([(30.0, 30.0), (30.0, 30.0)]))
        travel = world.poses()[0, 0] - before
        last = travel if travel > 1e-9 else last  # (a bot at rest drifts by 1e-17 m in pymunk's float steps)
    gap = world.poses()[1, 0] - world.poses()[0, 0]
    cheeks = 0.053328 + math.sqrt(0.06**2 - 0.0274977**2)
    assert abs(travel) < 1e-12 and round(cheeks, 5) == 0.10666 and 0.0 < last < 0.001
    assert cheeks - last < gap <= cheeks + last  # (the last steps, 0.53 mm at 30 units, were made against where the other stood)
