"""Exercise 3: odometry from the wheel encoders, as an estimator a run can use.

Check your work with:  ctsim lab check 3 encoders.py
"""


import numpy as np


class Odometry:
    """Dead reckoning from encoder ticks. The run calls reset() once, then update() at every
    sample (the first one at t = 0, with zero ticks) and reads `pose` after each update."""

    def reset(self, robot, pose):
        """robot: the RobotSpec (robot.wheel_diameter, robot.track_width in m,
        robot.encoders.ticks_per_rev); pose: the start pose (x, y, theta) in m, m, rad."""
        self.robot = robot
        self.pose = np.array(pose, dtype=float)

    def update(self, readings):
        """readings.encoder_ticks: (left, right) ticks counted during the last step."""
        raise NotImplementedError("your code here")
