"""Follow a path with Omni-Curve-Parameters, on any wheeled chassis (OCP §2, §3.7).

Pure pursuit in the body frame: the point `lookahead_m` ahead on the path is the target. A chassis
that can move in every direction (B of rank 3) heads for it with the float angle β and turns its
body towards the path's direction on the way; one that cannot (a car, a differential drive) steers
the pure-pursuit arc through it, κ = 2 y/L². The wanted twist becomes an OCP configuration (κ_n, β)
by the core's `twist_to_ocp`; where the chassis's configuration space blocks it (a steering limit,
a wheel at the ICR) the curvature is relaxed towards straight until it is allowed, and the speed
v_n is capped by what the configuration allows (its v_max). It runs on its own encoder odometry,
in the frame of its start pose, and succeeds at the path's last point.
"""

from __future__ import annotations

import math

import numpy as np

from bots.chassis_commands import believed_chassis, top_speed
from bots.commands import STOP, Command, CurveCommand
from bots.controller import Status, register
from bots.odometry.chassis import ChassisEncoderOdometry
from bots.readings import Readings
from bots.spec import RobotSpec
from sim.kinematics import relative_increment, wrap_angle
from sim.kinematics.chassis import is_feasible, motion_subspaces, nearest_feasible
from sim.kinematics.ocp import configuration_space, kappa_g_for, twist_to_ocp

ARRIVED = 0.02
"""The path is done when the robot believes itself this close to its last point (m)."""
HEADING_GAIN = 1.5
"""Yaw rate (rad/s per rad) with which a holonomic chassis turns its body to the path's direction."""


def parse_path(text: str) -> np.ndarray:
    """Points (k, 2) m from "x,y;x,y;..." (in the frame of the start pose)."""
    try:
        points = np.array([[float(v) for v in p.split(",")] for p in text.split(";") if p.strip()], dtype=float)
    except ValueError:
        points = np.zeros((0, 3))
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 1 or not np.all(np.isfinite(points)):
        raise ValueError(f"path must be points 'x,y;x,y;...' in metres, got {text!r}")
    return points


@register("follow_path_ocp")
class FollowPathOCP:
    """Drives through the points of `path` ("x,y;..." m, start frame) at `speed` (fraction of the
    chassis's top speed) with look-ahead `lookahead_m`, on any general chassis."""

    def __init__(self, path: str = "1,0;1,1;0,1;0,0", speed: float = 0.5, lookahead_m: float = 0.3):
        if not (0 < speed <= 1 and lookahead_m > 0):
            raise ValueError(f"need 0 < speed <= 1 and lookahead_m > 0, got {speed} and {lookahead_m}")
        self.path = np.vstack([[0.0, 0.0], parse_path(path)])
        self.speed, self.lookahead = speed, lookahead_m
        self.status = Status.RUNNING

    def reset(self, robot: RobotSpec) -> None:
        if robot.chassis is None:
            raise ValueError(f"follow_path_ocp drives a general chassis; {robot.name!r} is a differential drive "
                             "(use go_to_pose or drive_square)")
        self.robot = robot
        self.odometry = ChassisEncoderOdometry()
        self.odometry.reset(robot, np.zeros(3))
        self.kappa_g = kappa_g_for(robot.chassis.chassis)
        self.segment, self.beta_prev, self.status = 0, 0.0, Status.RUNNING

    def step(self, t: float, readings: Readings) -> Command:
        self.odometry.update(readings)
        if self.status is not Status.RUNNING:
            return STOP
        pose = self.odometry.pose
        target, tangent, remaining = self._target(pose[:2])
        if remaining < ARRIVED:
            self.status = Status.SUCCESS
            return STOP
        body = relative_increment(pose, np.array([*target, 0.0]))[:2]
        chassis = believed_chassis(self.robot, readings)
        v = self.speed * top_speed(self.robot) * min(1.0, remaining / self.lookahead)
        holonomic = motion_subspaces(chassis).B.shape[1] == 3
        distance = max(float(np.hypot(*body)), 1e-9)
        if holonomic:
            omega = HEADING_GAIN * wrap_angle(tangent - pose[2])
            twist = np.array([v * body[0] / distance, v * body[1] / distance, omega])
            line = 0.0
        else:
            twist = np.array([v, 0.0, 2 * v * body[1] / distance**2])
            if not is_feasible(chassis, twist):
                twist = nearest_feasible(chassis, twist)
            # a chassis that lost a wheel may only move along a skewed line: its OCP line is that one
            line = math.atan2(twist[1], twist[0]) if np.hypot(twist[0], twist[1]) > 1e-12 else 0.0
        kappa_n, beta, v_s = (float(x) for x in twist_to_ocp(
            twist, self.kappa_g, convention="continuity" if holonomic else "line", beta_prev=self.beta_prev, beta0=line))
        kappa_n = self._allowed(kappa_n, beta)
        self.beta_prev = beta
        v_max = float(configuration_space(self.robot.chassis.chassis, kappa_n, beta).v_max)
        v_n = math.copysign(min(abs(v_s), v_max) / top_speed(self.robot), v_s) if math.isfinite(v_max) else v_s / top_speed(self.robot)
        return CurveCommand(kappa_n, beta, float(np.clip(v_n, -1.0, 1.0)))

    def _allowed(self, kappa_n: float, beta: float) -> float:
        """The configuration's curvature, relaxed towards straight until no actuator limit blocks it."""
        for fraction in np.linspace(1.0, 0.0, 21):
            if not configuration_space(self.robot.chassis.chassis, kappa_n * fraction, beta).blocked:
                return kappa_n * fraction
        return 0.0

    def _past_end(self, position: np.ndarray) -> bool:
        """Whether the robot has passed the current segment's end (a chassis that cannot turn tightly
        may miss the corner by more than the look-ahead)."""
        a, b = self.path[self.segment], self.path[self.segment + 1]
        return float(np.dot(position - b, b - a)) > 0.0

    def _target(self, position: np.ndarray) -> tuple[np.ndarray, float, float]:
        """The look-ahead point on the path, the current segment's direction, and the path length left (m)."""
        while self.segment < len(self.path) - 2 and (np.hypot(*(self.path[self.segment + 1] - position)) < self.lookahead
                                                     or self._past_end(position)):
            self.segment += 1
        a, b = self.path[self.segment], self.path[self.segment + 1]
        tangent = math.atan2(b[1] - a[1], b[0] - a[0])
        later = np.diff(self.path[self.segment + 1:], axis=0)
        remaining = float(np.hypot(*(b - position)) + np.hypot(later[:, 0], later[:, 1]).sum())
        if self.segment == len(self.path) - 2 and np.hypot(*(b - position)) < self.lookahead:
            return b, tangent, remaining
        d = b - a
        along = np.clip(np.dot(position - a, d) / max(np.dot(d, d), 1e-12), 0.0, 1.0)
        ahead = a + along * d + self.lookahead * d / max(np.hypot(*d), 1e-12)
        return ahead, tangent, remaining
