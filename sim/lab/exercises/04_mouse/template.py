"""Exercise 4: odometry from the optical mouse sensor, as an estimator a run can use.

Check your work with:  ctsim lab check 4 mouse.py
"""

import numpy as np


class Odometry:
    """Dead reckoning from mouse counts. The run calls reset() once, then update() at every
    sample (the first one at t = 0, with zero counts) and reads `pose` after each update."""

    def reset(self, robot, pose):
        """robot: the RobotSpec (robot.mouse.mount = (m_x, m_y) in m in the body frame, x forward,
        y left, origin at the axle centre; robot.mouse.dpi counts per inch); pose: the start pose
        (x, y, theta) in m, m, rad. Raise a ValueError for a mount that cannot see rotation."""
        self.robot = robot
        self.pose = np.array(pose, dtype=float)

    def update(self, readings):
        """readings.mouse_counts: (forward, left) counts the sensor saw during the last step."""
        raise NotImplementedError("your code here")
