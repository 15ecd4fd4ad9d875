import math

import numpy as np

from bots.commands import Twist
from sim.lab.kit import EncoderOdometry


def wrap(angle):
    return (angle + math.pi) % (2 * math.pi) - math.pi


class Driver:
    speed = 0.03

    def __init__(self, waypoints, heading):
        self.waypoints = [np.array(w, dtype=float) for w in waypoints]
        self.heading = float(heading)

    def reset(self, robot):
        self.odometry = EncoderOdometry()
        self.odometry.reset(robot, np.zeros(3))
        self.leg = 0

    def step(self, t, readings):
        self.odometry.update(readings)
        x, y, theta = self.odometry.pose
        while self.leg < len(self.waypoints):
            dx, dy = self.waypoints[self.leg] - (x, y)
            distance = math.hypot(dx, dy)
            if distance < 0.01:
                self.leg += 1
                continue
            error = wrap(math.atan2(dy, dx) - theta)
            if abs(error) > 0.2:
                return Twist(0.0, max(-2.0, min(2.0, 4.0 * error)))
            return Twist(min(self.speed, 2.0 * distance + 0.02), 4.0 * error)
        return self.turn_to(self.heading - theta)

    def turn_to(self, error):
        error = wrap(error)
        if abs(error) < 0.02:
            return Twist(0.0, 0.0)
        return Twist(0.0, math.copysign(min(2.0, max(0.3, 4.0 * abs(error))), error))
