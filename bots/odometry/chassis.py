"""Odometry for a robot on any wheeled chassis, from its wheel encoders or its mouse sensors.

Both estimators find the step's body twist ξ·dt by least squares and lay it down exactly,
pose ← pose ∘ se2_exp(ξ·dt), the same motion model the world drives with:

- encoders: every wheel's encoder angle Δφ and its steering sensor's β give the core's forward
  kinematics (rolling rows of all wheels, sliding rows of fixed and steered ones). Wheels that agree
  on one rigid motion give it exactly. Driven wheels commanded against each other slip; the world
  settles them by the same least squares, so the estimate stays exact and the misfit (`residual`)
  equals the world's slip. Random slip of the rims (EncoderSpec.slip_std) moves the body by other
  speeds than the wheels turn: it shows as encoder error.
- mouse: each sensor at (m_x, m_y) reads the ground under it, (t_x − ω m_y, t_y + ω m_x) for the
  step's twist t (DESIGN.md §4); one sensor gives two equations, the chassis's sliding constraints
  more (a car or differential drive: enough), two sensors four. A set that cannot observe all three
  components (one mouse on an omni chassis) is refused at reset, with what to add.
"""

from __future__ import annotations

import math

import numpy as np

from bots.readings import Readings
from bots.spec import RobotSpec
from sim.kinematics import apply_increment, se2_exp
from sim.kinematics.chassis import (
    Chassis,
    WheelType,
    forward_pinv,
    forward_system,
    sliding_rows,
)
from sim.kinematics.mouse import counts_per_metre

_RANK_TOL = 1e-9
"""Relative singular-value cut-off for the mouse equations' rank (as the core's)."""


class _TwistOdometry:
    """Shared dead reckoning: `displacement(readings)` gives ξ·dt for the step, laid down by se2_exp."""

    name = "twist"

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        if robot.chassis is None:
            raise ValueError(f"robot {robot.name!r} has no general chassis; use bots.odometry's estimators")
        self.robot = robot
        self.chassis: Chassis = robot.chassis.chassis
        self.pose = np.asarray(pose, dtype=np.float64).copy()

    def displacement(self, readings: Readings) -> np.ndarray:
        raise NotImplementedError

    def update(self, readings: Readings) -> None:
        self.pose = apply_increment(self.pose, se2_exp(self.displacement(readings)))


class ChassisEncoderOdometry(_TwistOdometry):
    """Every wheel's encoder and steering angle through the core's forward kinematics. `residual` (m)
    is the last step's least-squares misfit: how far the wheels disagreed, the slip the robot can see."""

    name = "encoders"

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        super().reset(robot, pose)
        self.rad_per_tick = 2 * math.pi / robot.encoders.ticks_per_rev
        self._solver: tuple = ()
        self.residual = 0.0

    def displacement(self, readings: Readings) -> np.ndarray:
        beta = readings.steering if len(readings.steering) == self.chassis.n else self.chassis.beta
        key = beta.tobytes()
        if not self._solver or self._solver[0] != key:
            a, _ = forward_system(self.chassis, np.zeros(self.chassis.n), beta)
            self._solver = (key, a, forward_pinv(a))
        angles = np.asarray(readings.encoder_ticks, dtype=np.float64) * self.rad_per_tick
        _, rhs = forward_system(self.chassis, angles, beta)
        displacement = self._solver[2] @ rhs
        self.residual = float(np.linalg.norm(self._solver[1] @ displacement - rhs))
        return displacement


class ChassisMouseOdometry(_TwistOdometry):
    """One or two mouse sensors, with the chassis's sliding constraints, at the dpi the robot believes."""

    name = "mouse"

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        super().reset(robot, pose)
        self.mice = [m for m in (robot.mouse, robot.chassis.mouse2) if m is not None]
        if not self.mice:
            raise ValueError(f"robot {robot.name!r} has no mouse sensor: mouse odometry does not apply")
        rows, _ = self._equations(self.chassis.beta)
        if np.linalg.matrix_rank(rows, tol=_RANK_TOL * max(1.0, np.abs(rows).max())) < 3:
            raise ValueError(
                f"robot {robot.name!r}: {len(self.mice)} mouse sensor(s) and the chassis's constraints cannot tell "
                "all of (v_x, v_y, ω): add a second mouse (chassis.mouse2) at another mount point")
        self._solver: tuple = ()

    def _equations(self, beta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rows (k, 3) mapping a twist to the sensors' readings (m) and the sliding constraints (= 0)."""
        rows = []
        for mouse in self.mice:
            m_x, m_y = mouse.mount
            rows += [(1.0, 0.0, -m_y), (0.0, 1.0, m_x)]
        c = self.chassis
        constrains = np.isin(c.kind, (WheelType.FIXED, WheelType.STEERED))
        slide = sliding_rows(c.alpha[constrains], beta[constrains], c.l[constrains]).reshape(-1, 3)
        return np.vstack([np.array(rows), slide]), np.zeros(len(slide))

    def displacement(self, readings: Readings) -> np.ndarray:
        beta = readings.steering if len(readings.steering) == self.chassis.n else self.chassis.beta
        key = beta.tobytes()
        if not self._solver or self._solver[0] != key:
            rows, _ = self._equations(beta)
            self._solver = (key, np.linalg.pinv(rows, rcond=_RANK_TOL))
        counts = [readings.mouse_counts, readings.mouse2_counts][: len(self.mice)]
        metres = np.concatenate([np.asarray(c, dtype=np.float64) / counts_per_metre(m.dpi) for c, m in zip(counts, self.mice)])
        pinv = self._solver[1]
        return pinv[:, : len(metres)] @ metres


def mouse_applies(robot: RobotSpec) -> bool:
    """Whether the robot's mouse sensors (with its chassis's constraints) observe its whole motion."""
    try:
        ChassisMouseOdometry().reset(robot, np.zeros(3))
    except ValueError:
        return False
    return True


def chassis_estimators(robot: RobotSpec) -> list:
    """The estimators a run compares for a chassis robot: encoders, and the mouse where it observes all."""
    return [ChassisEncoderOdometry(), *([ChassisMouseOdometry()] if mouse_applies(robot) else [])]
