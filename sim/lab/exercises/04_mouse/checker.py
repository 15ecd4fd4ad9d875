"""Checker of exercise 4: the student's mouse estimator in a run, against the shipped inverse
mouse model fed the same counts; a mount on the axle line must be refused in reset()."""

import math

import numpy as np

from bots.odometry import MouseOdometry
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


class Chord(MouseOdometry):
    """The arc length laid as if it were the chord."""

    def update(self, readings):
        s, alpha = self.arc(readings)
        x, y, theta = self.pose
        mid = theta + alpha / 2
        self.pose = np.array([x + s * math.cos(mid), y + s * math.sin(mid), theta + alpha])


class Flipped(MouseOdometry):
    """alpha = -lateral/m_x, and s = forward + alpha*m_y with that alpha."""

    def arc(self, readings):
        s, alpha = super().arc(readings)
        return s - 2 * alpha * self.model.mount[1], -alpha


class NoLateralOffset(MouseOdometry):
    """s = forward, the alpha*m_y term left out."""

    def arc(self, readings):
        s, alpha = super().arc(readings)
        return s - alpha * self.model.mount[1], alpha


def spec_for(scenario):
    return robot({}).with_changes(mouse={"mount": tuple(float(v) for v in scenario["mount"])})


def check(scenario, student):
    spec = spec_for(scenario)
    if scenario["mount"][0] == 0:
        return refused(student, spec)
    mistakes = {"chord": Chord(), "flipped": Flipped(), "no_my": NoLateralOffset()}
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
