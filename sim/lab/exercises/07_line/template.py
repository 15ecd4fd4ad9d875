"""Exercise 7: follow a line to the goal, as a controller a run can use.

Check your work with:  ctsim lab check 7 line.py
"""

from bots.commands import Twist, WheelSpeeds  # noqa: F401  (what step() returns)

BLACK = 0x350
"""A line sensor reading above this sees the black line (0 white .. 1023 black)."""


class LineFollower:
    """Follows the black line from the start to the goal at its end."""

    def reset(self, robot):
        """robot: the RobotSpec; its two line sensors sit 9 mm ahead of the axle, 4 mm left and
        right of the centre line, so that both see a 24 mm line when the robot is on it."""
        self.robot = robot

    def step(self, t, readings):
        """Called every 10 ms; readings.line = (left, right) sensor values. Returns a command:
        Twist(v m/s, omega rad/s) or WheelSpeeds(left, right m/s)."""
        raise NotImplementedError("your code here")
