"""Commands for a robot on a general chassis, turned into wheel speeds and steering angles by the core.

The robot knows its chassis as its description states it, at the steering angles its sensors read,
with the faults its fault observer reports (`Readings.failures`): `believed_chassis`. A twist or OCP
command is checked against that chassis's feasible set (the core's B after the faults) and then
against the steering limits of its steered wheels (each may take an angle or its mirror, rolling
backwards): a twist the chassis cannot perform is refused (`InfeasibleCommand`, naming the wheels that
would slide, the drives that are missing, or the wheels that would have to steer beyond their limits,
with the angles) or, if the robot's `infeasible` policy is "project", replaced by the nearest
feasible twist (`nearest_feasible`) and then by the tightest turn at its speed (`nearest_steerable`),
and reported in the set-point's `note`. Wheel speeds beyond a motor's limit are scaled down together,
which keeps the path (the ICR) and slows the motion. The steering angles sent are within the limits,
so the world's steering stops are never reached by a twist.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from bots.commands import (
    BadCommand,
    Command,
    CurveCommand,
    Twist,
    WheelCommands,
    WheelSpeeds,
)
from bots.readings import Readings
from bots.spec import RobotSpec
from sim.kinematics.chassis import (
    Chassis,
    InfeasibleTwist,
    check_feasible,
    check_steering,
    degrade,
    inverse_kinematics,
)
from sim.kinematics.ocp import kappa_g_for, ocp_to_twist, v_max_for


class InfeasibleCommand(BadCommand):
    """A twist (or OCP command) the chassis cannot perform in its current state, refused."""


@dataclass(frozen=True)
class ChassisSetpoint:
    """What the drive is told: wheel speeds `phi_dot` (n,) rad/s and wheel-plane angles `beta` (n,) rad;
    `twist` the body twist they realise (None for raw wheel commands); `note` says what was projected."""

    phi_dot: np.ndarray
    beta: np.ndarray
    twist: np.ndarray | None = None
    note: str | None = None


def believed_chassis(robot: RobotSpec, readings: Readings) -> Chassis:
    """The chassis as the robot knows it: nominal, at its sensed steering angles, with its reported faults."""
    chassis = robot.chassis.chassis
    if len(readings.steering) == chassis.n:
        chassis = chassis.with_beta(readings.steering)
    return degrade(chassis, *readings.failures) if readings.failures else chassis


def wheel_limits(robot: RobotSpec) -> np.ndarray:
    """Fastest wheel speed of each wheel (rad/s): its rim-speed limit, else the motor's top speed."""
    c = robot.chassis.chassis
    return np.where(np.isfinite(c.max_speed), c.max_speed / c.radius, robot.motor.max_wheel_speed)


def top_speed(robot: RobotSpec) -> float:
    """v_max of the OCP (m/s): the slowest driven wheel's rim-speed limit (OCP §2.6)."""
    c = robot.chassis.chassis
    return float(min(v_max_for(c), np.min(wheel_limits(robot) * c.radius)))


def chassis_setpoints(command: Command, robot: RobotSpec, readings: Readings) -> ChassisSetpoint:
    """Wheel set-points for a command on a robot with a general chassis (see the module docstring)."""
    chassis = believed_chassis(robot, readings)
    if isinstance(command, WheelCommands):
        return _raw(command, chassis)
    if isinstance(command, WheelSpeeds):
        if command.left == 0 and command.right == 0:  # STOP, which every behaviour returns when done
            return ChassisSetpoint(np.zeros(chassis.n), chassis.beta.copy(), np.zeros(3))
        raise BadCommand(f"{command!r} is for a differential drive; {robot.name} takes WheelCommands, Twist or CurveCommand")
    if isinstance(command, Twist):
        twist = np.array([command.v, command.vy, command.omega], dtype=float)
    elif isinstance(command, CurveCommand):
        twist = ocp_to_twist(command.kappa_n, command.beta, command.v_n * top_speed(robot),
                             kappa_g_for(robot.chassis.chassis))
    else:
        raise BadCommand(f"expected WheelCommands, Twist or CurveCommand, got {type(command).__name__}: {command!r}")
    if not np.all(np.isfinite(twist)):
        raise BadCommand(f"non-finite command {command!r}")
    notes = []
    for check in (check_feasible, check_steering):
        try:
            check(chassis, twist)
        except InfeasibleTwist as err:
            if robot.chassis.infeasible == "refuse":
                raise InfeasibleCommand(f"refused: {err}") from None
            twist = err.nearest
            notes.append(f"projected: {err}")
    wheels = inverse_kinematics(chassis, twist)
    scale = max(1.0, float(np.max(np.abs(wheels.phi_dot) / wheel_limits(robot), where=chassis.driven, initial=0.0)))
    return ChassisSetpoint(wheels.phi_dot / scale, wheels.beta, twist / scale, "; ".join(notes) or None)


def _raw(command: WheelCommands, chassis: Chassis) -> ChassisSetpoint:
    speeds = np.asarray(command.speeds, dtype=float)
    steering = chassis.beta.copy() if command.steering is None else np.asarray(command.steering, dtype=float)
    if speeds.shape != (chassis.n,) or steering.shape != (chassis.n,):
        raise BadCommand(f"WheelCommands needs {chassis.n} speeds and {chassis.n} steering angles "
                         f"({', '.join(chassis.names)}), got {speeds.shape[0] if speeds.ndim else 1} and "
                         f"{steering.shape[0] if steering.ndim else 1}")
    if not (np.all(np.isfinite(speeds)) and np.all(np.isfinite(steering))):
        raise BadCommand(f"non-finite command {command!r}")
    return ChassisSetpoint(speeds, steering)
