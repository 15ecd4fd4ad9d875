"""Checker of exercise 4: the student's mouse estimator in a run, against the shipped inverse
mouse model fed the same counts; a mount on the axle line must be refused in reset()."""

import math

import numpy as np

from bots.odometry.mouse import MouseOdometry
from sim.kinematics import counts_per_metre
from sim.lab.checking import Outcome
from sim.lab.runs import check_estimator, robot
from sim.lab.student import StudentError

SEGMENTS = 4


def draw(rng, index, ranges):
    """The first hidden mount on the axle line; then a lever of either sign and four segments of
    1-2 s with rim speeds up to 0.2 m/s,
    read every `dt` s."""
    lever = 0.0 if index == 0 else float(rng.uniform(*ranges["lever"]) * rng.choice([-1.0, 1.0]))
    segments = [[float(rng.uniform(1, 2)), *map(float, rng.uniform(-0.2, 0.2, 2))] for _ in range(SEGMENTS)]
    return {"mount": [lever, float(rng.uniform(*ranges["side"]))], "segments": segments, "dt": ranges["dt"]}


class Mouse:
    """The inverse mouse model as a student writes it (alpha = lateral/m_x, s = forward + alpha·m_y,
    the chord along the mid-angle), with one step of it wrong: `lateral_sign` -1 flips alpha,
    `lever` False leaves alpha·m_y out, `chord` False lays the arc length as if it were the chord."""

    name = "mistaken"

    def __init__(self, lateral_sign=1.0, lever=True, chord=True):
        self.lateral_sign, self.lever, self.chord = lateral_sign, lever, chord

    def reset(self, robot, pose):
        self.mount = tuple(float(m) for m in robot.mouse.mount)
        self.per_metre = float(counts_per_metre(robot.mouse.dpi))
        self.pose = np.array(pose, dtype=float)

    def update(self, readings):
        forward, lateral = (v / self.per_metre for v in np.asarray(readings.mouse_counts, dtype=np.float64).tolist())
        alpha = self.lateral_sign * lateral / self.mount[0]
        s = forward + (alpha * self.mount[1] if self.lever else 0.0)
        length = s * float(np.sinc(alpha / (2 * math.pi))) if self.chord else s
        x, y, theta = self.pose
        mid = theta + alpha / 2
        self.pose = np.array([x + length * math.cos(mid), y + length * math.sin(mid), theta + alpha])


def spec_for(scenario):
    return robot({}).with_changes(mouse={"mount": tuple(float(v) for v in scenario["mount"])})


def check(scenario, student):
    spec = spec_for(scenario)
    if scenario["mount"][0] == 0:
        return refused(student, spec)
    mistakes = {"chord": Mouse(chord=False), "flipped": Mouse(lateral_sign=-1.0), "no_my": Mouse(lever=False)}
    return check_estimator(scenario, spec, student, MouseOdometry(), mistakes)


def refused(student, spec):
    """reset() on an axle-line mount must raise a ValueError (or a subclass)."""
    try:
        student.method(student.new("Odometry"), "reset", spec, np.zeros(3), what="Odometry.reset()")
    except StudentError as err:
        if err.value_error:
            return Outcome("ValueError", err.exception, True)
        raise
    return Outcome("ValueError", "accepted", False, hint="axle")
