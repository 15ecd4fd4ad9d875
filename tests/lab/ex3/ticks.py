import math

import numpy as np


class Odometry:
    def reset(self, robot, pose):
        self.per_tick = math.pi * robot.wheel_diameter / robot.encoders.ticks_per_rev
        self.track = robot.track_width
        self.pose = np.array(pose, dtype=float)

    def update(self, readings):
        left, right = readings.encoder_ticks
        s, alpha = (left + right) / 2, (right - left) / self.track
        chord = s * (math.sin(alpha / 2) / (alpha / 2) if alpha else 1.0)
        x, y, theta = self.pose
        self.pose = np.array([x + chord * math.cos(theta + alpha / 2), y + chord * math.sin(theta + alpha / 2), theta + alpha])
