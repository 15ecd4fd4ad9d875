"""Shipped behaviours, registered by name for the command line (importing this registers them),
and `make`, which builds any controller by name or file with them registered.

Modules: `base` (odometry, composition), `motion` (drive, turn, go to pose, square, teleop),
`floor` (line following, hole avoidance), `walls` (maze solving, wandering), `ocp_path` (path
following with Omni-Curve-Parameters on any general chassis).
"""

from bots.behaviours.base import Behaviour, Look, Plan, Sequence, TickOdometry
from bots.behaviours.floor import AvoidHoles, FollowLine
from bots.behaviours.motion import (
    DriveDistance,
    DriveTo,
    GoToPose,
    Idle,
    Square,
    Stop,
    Teleop,
    Turn,
)
from bots.behaviours.ocp_path import FollowPathOCP
from bots.behaviours.walls import SolveMaze, Wander
from bots.controller import make

__all__ = [
    "AvoidHoles", "Behaviour", "DriveDistance", "DriveTo", "FollowLine", "FollowPathOCP", "GoToPose", "Idle", "Look", "Plan", "Sequence",
    "SolveMaze", "Square", "Stop", "Teleop", "TickOdometry", "Turn", "Wander", "make",
]  # fmt: skip
