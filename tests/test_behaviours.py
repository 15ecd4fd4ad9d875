"""Behaviour registry, parameters, student files and teleop: no world needed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bots.behaviours import Behaviour, Teleop, TickOdometry, make
from bots.commands import STOP, Twist, WheelSpeeds
from bots.controller import REGISTRY, ControllerError, Status, parameters, reset
from bots.ctbot import CTBOT
from bots.readings import Readings
from bots.spec import RobotSpec

SHIPPED = {
    "idle", "stop", "drive_distance", "turn", "go_to_pose", "square", "teleop",
    "follow_line", "avoid_holes", "solve_maze", "follow_wall", "wander",
}  # fmt: skip


def blank(robot: RobotSpec = CTBOT) -> Readings:
    """Readings of `robot` with every sensor at zero (white floor, nothing in sight)."""
    return Readings(
        ir_raw=np.zeros(len(robot.ir), dtype=np.int64),
        ir_distance=np.full(len(robot.ir), np.nan),
        line=np.zeros(len(robot.line), dtype=np.int64),
        border=np.zeros(len(robot.border), dtype=np.int64),
        light=np.zeros(len(robot.light), dtype=np.int64),
    )


def test_every_shipped_name_builds_with_defaults_and_steps():
    make("idle")  # imports and registers the behaviours
    assert SHIPPED <= set(REGISTRY)
    for name in SHIPPED:
        controller = make(name)
        reset(controller, CTBOT)
        command = controller.step(0.0, blank())
        assert isinstance(command, (WheelSpeeds, Twist)), name
        assert controller.status in Status


def test_parameters_carry_units_and_types():
    make("idle")
    for name in SHIPPED:
        for key, p in parameters(REGISTRY[name]).items():
            assert p.default is not p.empty, f"{name}.{key} needs a default"
    drive = make("drive_distance", {"distance_m": "-0.25", "speed_m_s": "0.1"})
    assert (drive.distance, drive.speed) == (-0.25, 0.1)
    square = make("square", {"clockwise": "yes", "laps": "2"})
    assert (square.sign, square.laps) == (-1.0, 2)


@pytest.mark.parametrize(
    ("spec", "params", "message"),
    [
        ("drive_distanc", {}, "did you mean 'drive_distance'"),
        ("no_such_thing", {}, "known: "),
        ("turn", {"angle": "90"}, "parameters: angle_deg, speed_m_s"),
        ("turn", {"angle_deg": "ninety"}, "parameter angle_deg"),
        ("square", {"clockwise": "maybe"}, "expected true or false"),
        ("square", {"side_m": "-1"}, "positive side"),
        ("solve_maze", {"hand": "middle"}, "'left' or 'right'"),
        ("avoid_holes", {"inner": "nothing"}, "unknown controller 'nothing'"),
    ],
)
def test_bad_names_and_parameters_say_what_is_wrong(spec, params, message):
    with pytest.raises(ControllerError, match=message):
        make(spec, params)


STUDENT = '''
from bots.commands import Twist

class Forward:
    def __init__(self, speed_m_s: float = 0.1):
        self.speed = speed_m_s

    def step(self, t, readings):
        return Twist(self.speed, 0.0)

def spin(t, readings):
    return Twist(0.0, 1.0)
'''


def test_a_students_file_loads_by_path_and_by_name(tmp_path):
    path = tmp_path / "mine.py"
    path.write_text(STUDENT)
    forward = make(str(path), {"speed_m_s": "0.2"})
    assert forward.step(0.0, Readings()) == Twist(0.2, 0.0)
    spin = make(f"{path}:spin")
    assert spin.step(0.0, Readings()) == Twist(0.0, 1.0)
    with pytest.raises(ControllerError, match="defines no 'nope'"):
        make(f"{path}:nope")


def test_a_broken_students_file_names_its_line(tmp_path):
    path = tmp_path / "broken.py"
    path.write_text("x = 1\ny = 1 / 0\n")
    with pytest.raises(ControllerError, match=r"broken.py:2: ZeroDivisionError"):
        make(str(path))


@pytest.mark.parametrize(("name", "sensors"), [("follow_line", "line"), ("avoid_holes", "border"), ("solve_maze", "ir")])
def test_a_robot_without_the_sensors_is_refused(name, sensors):
    with pytest.raises(ValueError, match=f"needs .* {sensors} sensors; robot 'bare' has 0"):
        reset(make(name), CTBOT.with_changes(name="bare", **{sensors: ()}))


def test_teleop_maps_held_keys_to_a_twist():
    teleop = Teleop(speed_m_s=0.2, turn_deg_s=90.0)
    reset(teleop, CTBOT)
    assert teleop.step(0.0, Readings()) == Twist(0.0, 0.0)
    teleop.press("Up")
    teleop.press("a")
    assert teleop.step(0.01, Readings(time=0.01)) == Twist(0.2, math.pi / 2)
    teleop.press("right")  # cancels left
    teleop.release("up")
    assert teleop.step(0.02, Readings(time=0.02)) == Twist(0.0, 0.0)
    teleop.set_keys(["s", "space"])  # unknown keys are ignored
    assert teleop.step(0.03, Readings(time=0.03)) == Twist(-0.2, 0.0)
    assert teleop.status is Status.RUNNING


def test_tick_odometry_stays_within_a_tick_of_the_counts():
    """Commanded speeds that the wheels do not follow cannot pull the estimate off the counts by
    more than a tick."""
    odometry = TickOdometry(CTBOT)
    for k in range(200):
        odometry.update(Readings(time=k * 0.01, encoder_ticks=np.array([0, 1 if k % 10 == 0 else 0])), (0.4, -0.4))
    assert np.all(odometry.turned >= odometry.counted)
    assert np.all(odometry.turned <= odometry.counted + 1)
    assert odometry.pose[2] > 0  # the right wheel's ticks turned it left, whatever was commanded


def test_a_finished_behaviour_stops():
    class Once(Behaviour):
        def act(self, t, readings):
            return self.finish(Status.FAILURE)

    once = Once()
    reset(once, CTBOT)
    assert once.step(0.0, Readings()) == STOP
    assert once.status is Status.FAILURE
    assert once.step(0.01, Readings(time=0.01)) == STOP
