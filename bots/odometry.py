"""Odometry estimators: what a robot believes about its pose, from its own readings only.

An estimator is reset with the robot's description and its start pose, then takes each step's
readings and exposes `pose` (x, y m, heading rad). The comparison against ground truth happens in
the run loop's consumers, never here.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from bots.spec import RobotSpec
from sim.kinematics import apply_increment, arcs_from_ticks, wheel_increment
from sim.readings import Readings


class Estimator(Protocol):
    """Dead reckoning from readings."""

    name: str
    pose: np.ndarray

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None: ...
    def update(self, readings: Readings) -> None: ...


class EncoderOdometry:
    """Wheel encoders through the exact arc: ticks -> wheel arcs -> pose increment."""

    name = "encoders"

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        self.robot = robot
        self.pose = np.asarray(pose, dtype=np.float64).copy()

    def update(self, readings: Readings) -> None:
        s = arcs_from_ticks(readings.encoder_ticks, self.robot.wheel_radius, self.robot.encoders.ticks_per_rev)
        self.pose = apply_increment(self.pose, wheel_increment(s[0], s[1], self.robot.track_width))


def default_estimators(robot: RobotSpec) -> list[Estimator]:
    """The estimators a run compares by default for this robot."""
    return [EncoderOdometry()]
