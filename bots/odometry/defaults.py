"""The estimators a run compares by default for a robot."""

from __future__ import annotations

from bots.odometry.base import Estimator, Geometry, mouse_applies
from bots.odometry.chassis import chassis_estimators
from bots.odometry.encoder import EncoderOdometry
from bots.odometry.firmware import FirmwareOdometry
from bots.odometry.fused import FusedOdometry
from bots.odometry.mouse import MouseOdometry
from bots.spec import RobotSpec


def caveats() -> dict[str, str]:
    """Each shipped estimator's name -> where its covariance is known not to tell the truth
    (`ArcOdometry.caveat`), for a run's summary and table."""
    return {e.name: e.caveat for e in (EncoderOdometry(), FirmwareOdometry(), MouseOdometry(), FusedOdometry()) if e.caveat}


def default_estimators(robot: RobotSpec, geometry: Geometry | None = None) -> list[Estimator]:
    """The estimators a run compares by default for this robot: encoders and firmware always,
    mouse and fused where the robot has a mouse that can see rotation; for a general chassis, its
    encoder and mouse estimators (`bots.odometry.chassis`)."""
    if robot.chassis is not None:
        return chassis_estimators(robot)
    chosen: list[Estimator] = [EncoderOdometry(geometry), FirmwareOdometry(geometry)]
    if mouse_applies(robot):
        chosen += [MouseOdometry(), FusedOdometry(geometry=geometry)]
    return chosen
