"""Shipped behaviours, registered by name for the command line (importing this registers them).

Modules: `base` (odometry, composition), `motion` (drive, turn, go to pose, square, teleop),
`floor` (line following, hole avoidance), `walls` (maze solving, wandering).
"""

from bots.behaviours.base import Behaviour, Look, Plan, Sequence, TickOdometry
from bots.behaviours.motion import DriveDistance, DriveTo, GoToPose, Idle, Square, Stop, Teleop, Turn

__all__ = [
    "Behaviour", "DriveDistance", "DriveTo", "GoToPose", "Idle", "Look", "Plan", "Sequence",
    "Square", "Stop", "Teleop", "TickOdometry", "Turn",
]  # fmt: skip
