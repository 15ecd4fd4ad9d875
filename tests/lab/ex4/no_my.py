import math

import numpy as np


class Odometry:
    def reset(self, robot, pose):
        self.m_x, self.m_y = robot.mouse.mount
        if abs(self.m_x) < 1e-9:
            raise ValueError("a mouse on the axle line cannot see rotation")
        self.per_count = 0.0254 / robot.mouse.dpi
        self.pose = np.array(pose, dtype=float)

    def update(self, readings):
        forward, lateral = (c * self.per_count for c in readings.mouse_counts)
        alpha = lateral / self.m_x
        s = forward
        chord = s * (math.sin(alpha / 2) / (alpha / 2) if alpha else 1.0)
        x, y, theta = self.pose
        self.pose = np.array([x + chord * math.cos(theta + alpha / 2), y + chord * math.sin(theta + alpha / 2), theta + alpha])
