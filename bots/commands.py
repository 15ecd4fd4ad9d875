"""Motion commands a controller may return, and their translation to motor commands.

A command is wheel rim speeds, a body twist (v, omega) or Omni-Curve-Parameters; the kinematics
core turns the latter two into wheel speeds for the robot's chassis, scaled down together (the
path's curvature kept) where a wheel would exceed the motors' limit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bots.spec import RobotSpec
from sim.kinematics import wheel_speeds_from_twist
from sim.kinematics.chassis_presets import differential_drive
from sim.kinematics.ocp import kappa_g_for, ocp_to_twist


@dataclass(frozen=True)
class WheelSpeeds:
    """Rim speeds of the left and right wheel (m/s, forward positive)."""

    left: float
    right: float


@dataclass(frozen=True)
class Twist:
    """Body twist: forward speed v (m/s), yaw rate omega (rad/s, counter-clockwise) and sideways
    speed vy (m/s, to the left; only a holonomic chassis can, a differential drive refuses it)."""

    v: float
    omega: float
    vy: float = 0.0

    def __init__(self, v: float, omega: float, vy: float = 0.0):
        # (into the instance's dict: a frozen dataclass's own __init__ sets each field through
        # object.__setattr__, 0.8 µs a command, and behaviours make one every step)
        fields = self.__dict__
        fields["v"], fields["omega"], fields["vy"] = v, omega, vy


@dataclass(frozen=True)
class WheelCommands:
    """Per-wheel set-points of a robot on a general chassis: wheel speeds (rad/s, the chassis's sign
    convention) and wheel-plane angles β (rad) for the steered wheels (None: keep them as they are)."""

    speeds: tuple[float, ...]
    steering: tuple[float, ...] | None = None


@dataclass(frozen=True)
class CurveCommand:
    """Omni-Curve-Parameters (omni-curve-parameters.md §2.1, §2.6): nominal curvature kappa_n in
    [-2, 2] (0 straight, +-2 on the spot), direction beta (rad; 0 forward, pi backward for a
    differential drive) and speed v_n as a fraction of the chassis's top speed (0..1)."""

    kappa_n: float
    beta: float
    v_n: float


STOP = WheelSpeeds(0.0, 0.0)
Command = WheelSpeeds | Twist | CurveCommand | WheelCommands


class BadCommand(ValueError):
    """A command that is not one of the command types or holds a non-finite number."""


_last_conversion: tuple = (None, None, (0.0, 0.0))
"""The last command converted, its robot and its rim speeds. Commands and robots are immutable, and
a behaviour's odometry converts the command the run loop converted the step before: one
conversion a step instead of two."""


def wheel_speeds_for(command: Command, robot: RobotSpec) -> tuple[float, float]:
    """Rim speeds (m/s) for a command on `robot`, within its motor limit, curvature kept."""
    global _last_conversion
    last_command, last_robot, speeds = _last_conversion
    if command is last_command and robot is last_robot:
        return speeds
    speeds = _wheel_speeds(command, robot)
    _last_conversion = (command, robot, speeds)
    return speeds


def _wheel_speeds(command: Command, robot: RobotSpec) -> tuple[float, float]:
    if isinstance(command, WheelSpeeds):
        left, right = command.left, command.right
    elif isinstance(command, Twist):
        if command.vy != 0:
            raise BadCommand(f"refused {command!r}: a differential drive cannot move sideways (vy must be 0)")
        half = 0.5 * float(command.omega) * robot.believed_track  # `wheel_speeds_from_twist` in floats: once a step
        left, right = float(command.v) - half, float(command.v) + half
    elif isinstance(command, CurveCommand):
        chassis = differential_drive(track=robot.believed_track, wheel_radius=robot.wheel_radius)
        v_top = robot.max_wheel_surface_speed
        twist = ocp_to_twist(command.kappa_n, command.beta, command.v_n * v_top, kappa_g_for(chassis))
        left, right = wheel_speeds_from_twist(twist[0], twist[2], robot.believed_track)
    else:
        raise BadCommand(f"expected WheelSpeeds, Twist or CurveCommand, got {type(command).__name__}: {command!r}")
    left, right = float(left), float(right)
    if not (math.isfinite(left) and math.isfinite(right)):
        raise BadCommand(f"non-finite command {command!r}")
    limit = robot.max_wheel_surface_speed
    faster = abs(left) if abs(left) > abs(right) else abs(right)
    if faster <= limit:  # (within the limit: a scale of exactly 1, the speeds as they are)
        return left, right
    scale = faster / limit
    return left / scale, right / scale


def command_per_speed(robot: RobotSpec) -> tuple[float, float]:
    """Motor command units (e.g. 255 at full speed) per m/s of rim speed, for the left and the
    right wheel as the robot believes their radii (`RobotSpec.believed_wheel_radii`: a calibrated
    robot turns a wheel it believes larger more slowly for the same speed)."""
    return tuple(robot.motor.command_max / (robot.motor.max_wheel_speed * radius) for radius in robot.believed_wheel_radii)


def motor_commands(left: float, right: float, robot: RobotSpec) -> tuple[float, float]:
    """Signed motor commands (the motors' units, e.g. +-255) for rim speeds (m/s): plain floats
    (the run loop scales by `command_per_speed` itself, into its command array)."""
    per_left, per_right = command_per_speed(robot)
    return left * per_left, right * per_right
