"""Exercise 5: drive through waypoints to a pose, as a controller a run can use.

Check your work with:  ctsim lab check 5 drive.py
"""

import numpy as np

from bots.commands import Twist, WheelSpeeds  # noqa: F401  (what step() returns)
from sim.lab.kit import EncoderOdometry  # noqa: F401  (exercise 3's odometry, ready to use)


class Driver:
    """Drives from the start through `waypoints` and stops at the last one facing `heading`.

    waypoints: [[x, y], ...] in m and heading in rad, all in the robot's start frame (x ahead,
    y to the left, the start at the origin)."""

    def __init__(self, waypoints, heading):
        self.waypoints = [np.array(w, dtype=float) for w in waypoints]
        self.heading = float(heading)

    def reset(self, robot):
        """robot: the RobotSpec (wheel_diameter, track_width in m, encoders.ticks_per_rev)."""
        self.robot = robot

    def step(self, t, readings):
        """Called every 10 ms with this step's sensor readings (readings.encoder_ticks...);
        returns a command: Twist(v m/s, omega rad/s) or WheelSpeeds(left, right m/s)."""
        raise NotImplementedError("your code here")
