"""What an exercise's template may hand a student ready-made: an encoder odometry in plain Python
(the exact arc, exercise 3's answer), for the exercises that build on it (driving to a pose).

Standard library and numpy only: it is bound into the student's sandbox as it is, where the
project's compiled odometry (numba) is not there.
"""

from __future__ import annotations

import math

import numpy as np


class EncoderOdometry:
    """Dead reckoning from encoder ticks along exact arcs (seed 002, eqs 1.3-1.12), as the run's
    estimators are used: reset(robot, pose) once, update(readings) at every sample, then `pose`
    (x, y m; heading rad, continuous)."""

    def reset(self, robot, pose) -> None:
        self.per_tick = math.pi * robot.wheel_diameter / robot.encoders.ticks_per_rev
        self.track = float(robot.track_width)
        self.pose = np.array(pose, dtype=float)

    def update(self, readings) -> None:
        left, right = (float(t) * self.per_tick for t in np.asarray(readings.encoder_ticks).tolist())
        s, alpha = (left + right) / 2, (right - left) / self.track
        chord = s * float(np.sinc(alpha / (2 * math.pi)))  # s·sin(α/2)/(α/2), continuous at α = 0
        x, y, theta = self.pose
        self.pose = np.array([x + chord * math.cos(theta + alpha / 2), y + chord * math.sin(theta + alpha / 2), theta + alpha])
