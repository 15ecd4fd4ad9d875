"""An example estimator to submit to `ctsim evaluate`: the c't-Bot's encoder odometry integrated
with Euler's method, as a control loop of 100 ms would: every tenth reading, the distance the
wheels rolled since the last update is laid along the heading before it, and then the heading
turned. The shipped `encoders` estimate follows the exact arc at every reading, so this one
ranks below it. Its covariance grows with the distance driven, as a first guess would.

    ctsim evaluate docs/examples/euler_odometry.py:EulerOdometry --suite short
"""

import math

import numpy as np


class EulerOdometry:
    """Encoder odometry, Euler-integrated every `period` readings."""

    name = "euler"
    period = 10

    def reset(self, robot, pose):
        self.pose = np.array(pose, dtype=float)
        self.tick_m = math.pi * robot.wheel_diameter / robot.encoders.ticks_per_rev
        self.track_m = robot.track_width
        self.covariance = np.diag([1e-6, 1e-6, 1e-4])
        self.ticks = np.zeros(2)
        self.readings = 0

    def update(self, readings):
        self.ticks += readings.encoder_ticks
        self.readings += 1
        if self.readings % self.period:
            return
        left, right = self.ticks * self.tick_m
        self.ticks[:] = 0.0
        distance, turn = 0.5 * (left + right), (right - left) / self.track_m
        heading = self.pose[2]
        self.pose = self.pose + [distance * math.cos(heading), distance * math.sin(heading), turn]
        grown = 1e-4 * abs(distance)  # (m² and rad² per metre driven: a guess, not a model)
        self.covariance = self.covariance + np.diag([grown, grown, 10 * grown])
