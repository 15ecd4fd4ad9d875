"""Behaviours driving the c't-Bot in the shipped worlds, judged against ground truth.

The sensors are ideal apart from the encoders' ticks; the run loop's own estimators are switched off
(the behaviours keep their own odometry)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bots.behaviours import AvoidHoles, DriveDistance, GoToPose, Square, Turn, make
from bots.controller import Status
from bots.ctbot import CTBOT
from sim.kinematics import relative_increment
from sim.run.loop import RobotSetup, run
from sim.run.samples import RunResult
from sim.world.files import load_world

WORLDS = {name: load_world(name) for name in ("empty", "line", "maze", "holes_lights")}


def drive(world: str, controller, duration: float, start=None, until_goal: bool = False) -> RunResult:
    setup = RobotSetup(CTBOT, controller, type(controller).__name__, start=start, estimators=[])
    result = run(WORLDS[world], [setup], duration, until_goal=until_goal)
    assert result.error is None
    return result


def moved(result: RunResult) -> np.ndarray:
    """True end pose in the start frame (x m, y m, heading rad)."""
    truth = result.robots[0].truth_array()
    return relative_increment(truth[0], truth[-1])


@pytest.mark.parametrize("distance", [0.5, -0.3, 1.0])
def test_drive_distance_stops_within_a_millimetre(distance):
    controller = DriveDistance(distance)
    end = moved(drive("empty", controller, 10.0))
    assert controller.status is Status.SUCCESS
    # the drive believes itself within 0.2 mm (DISTANCE_TOLERANCE) when it stops; the motors' lag
    # over the last steps adds the rest of the millimetre the test's name promises
    assert end[0] == pytest.approx(distance, abs=1e-3)
    assert abs(end[1]) < 1e-3 and abs(end[2]) < math.radians(0.5)


@pytest.mark.parametrize("angle", [90.0, -45.0, 450.0])
def test_turn_turns_on_the_spot_within_a_tenth_of_a_degree(angle):
    controller = Turn(angle)
    end = moved(drive("empty", controller, 5.0))
    assert controller.status is Status.SUCCESS
    # the turn believes itself within 0.05° (ANGLE_TOLERANCE); the motors' lag adds the rest
    assert math.degrees(end[2]) == pytest.approx(angle, abs=0.1)
    assert math.hypot(end[0], end[1]) < 1e-6


@pytest.mark.parametrize("calibrated", [True, False])
def test_a_calibrated_robot_drives_by_its_belief(calibrated):
    """A c't-Bot whose track is 3 % wider and whose left wheel 1 % smaller than its description
    says: told so in its belief (`[belief]` track_correction, diameter_correction, as `ctsim
    umbmark` writes them), its behaviours' own odometry and its speeds turned into motor commands
    use them, and it turns 450 degrees within a tenth of a degree and drives a metre straight
    (within half a degree, a millimetre); believing the description, the turn falls 15 degrees
    short (450 x 0.995 / 1.03: the wheels' mean rim and the wider track) and the metre curves by
    more than 4 degrees (a 1 % smaller wheel on a 97 mm track: 6 degrees a metre)."""
    from bots.spec import BeliefSpec, EncoderSpec

    robot = CTBOT.with_changes(encoders=EncoderSpec(diameter_error=(-0.01, 0.0), track_error=0.03))
    if calibrated:
        robot = robot.with_changes(belief=BeliefSpec(diameter_correction=(-0.01, 0.0), track_correction=0.03))
    turned, driven = [], []
    for controller, into in ((Turn(450.0), turned), (DriveDistance(1.0), driven)):
        result = run(WORLDS["empty"], [RobotSetup(robot, controller, "c", estimators=[])], 15.0)
        assert result.error is None and controller.status is Status.SUCCESS
        into.append(moved(result))
    turn, (forward, _, heading) = math.degrees(turned[0][2]), driven[0]
    if calibrated:
        assert turn == pytest.approx(450.0, abs=0.1) and abs(math.degrees(heading)) < 0.5 and forward == pytest.approx(1.0, abs=1e-3)
    else:
        assert turn == pytest.approx(450.0 * 0.995 / 1.03, abs=0.2) and abs(math.degrees(heading)) > 4.0


@settings(max_examples=12)
@given(
    distance=st.floats(0.3, 1.5),
    bearing=st.floats(-math.pi, math.pi),
    heading=st.floats(-180.0, 180.0),
    facing=st.floats(-math.pi, math.pi),
)
def test_go_to_pose_reaches_random_targets_within_10_mm_and_2_degrees(distance, bearing, heading, facing):
    x, y = distance * math.cos(bearing), distance * math.sin(bearing)
    # start so that the way to the target is centred in the 3 m arena
    cx, cy = 1.5 - (x * math.cos(facing) - y * math.sin(facing)) / 2, 1.5 - (x * math.sin(facing) + y * math.cos(facing)) / 2
    controller = GoToPose(x, y, heading)
    result = drive("empty", controller, 20.0, start=(cx, cy, facing))
    end = moved(result)
    assert controller.status is Status.SUCCESS
    assert result.robots[0].collisions == 0
    assert math.hypot(end[0] - x, end[1] - y) < 0.010
    assert abs(math.remainder(end[2] - math.radians(heading), 2 * math.pi)) < math.radians(2)


@pytest.mark.parametrize("clockwise", [False, True])
def test_square_returns_to_its_start(clockwise):
    controller = Square(side_m=0.8, clockwise=clockwise)
    result = drive("empty", controller, 30.0, start=(1.1, 1.9 if clockwise else 1.1, 0.0))
    truth = result.robots[0].truth_array()
    end = moved(result)
    assert controller.status is Status.SUCCESS
    assert math.hypot(end[0], end[1]) < 0.005
    assert abs(math.remainder(end[2], 2 * math.pi)) < math.radians(1)
    side = np.ptp(truth[:, :2], axis=0)
    # extreme points of the path: each corner's turn on the spot and each leg's stop move them by millimetres
    assert side == pytest.approx([0.8, 0.8], abs=0.01)
    lateral = relative_increment(truth[0], truth)[:, 1]
    assert (lateral.min() < -0.79) if clockwise else (lateral.max() > 0.79)


def test_a_run_ends_as_done_when_its_controller_says_it_is_done():
    """A square of 0.5 m sides takes about 20 s: the run ends there, not at its 300 s limit."""
    controller = Square(side_m=0.5)
    result = run(WORLDS["empty"], [RobotSetup(CTBOT, controller, start=(1.0, 1.0, 0.0))], 300.0)
    assert controller.status is Status.SUCCESS
    assert result.reason == "done" and result.error is None
    assert result.time[-1] < 60.0


def test_follow_line_drives_a_lap_of_the_line_course():
    """The course is ~9 m long; one lap at 0.15 m/s takes about a minute."""
    controller = make("follow_line", {"laps": "1"})
    result = drive("line", controller, 70.0)
    truth = result.robots[0].truth_array()
    assert controller.status is Status.SUCCESS
    assert math.hypot(*(truth[-1, :2] - truth[0, :2])) < 0.1
    # went round the whole course: both bends and both straights, through the gap
    assert truth[:, 0].min() < 0.25 and truth[:, 0].max() > 3.75
    assert truth[:, 1].min() < 0.65 and truth[:, 1].max() > 2.15
    assert np.any((truth[:, 1] > 2.1) & (np.abs(truth[:, 0] - 2.075) < 0.01))
    assert result.robots[0].fell is False


def test_avoid_holes_keeps_a_bot_out_of_the_hole_it_drives_at():
    """The start faces a slot 0.9 m ahead: driving 2 m straight falls in, unless the reflex wraps it."""
    plain = drive("holes_lights", DriveDistance(2.0), 15.0)
    assert plain.robots[0].fell
    guarded = AvoidHoles(DriveDistance(2.0))
    result = drive("holes_lights", guarded, 15.0)
    assert not result.robots[0].fell
    assert result.robots[0].truth_array()[:, 0].max() > 1.2  # it did get to the hole's edge
