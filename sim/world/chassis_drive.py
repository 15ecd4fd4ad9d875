"""The world's drive for robots on a general wheeled chassis (the c't-Bot keeps its compiled kernel).

Per step and robot, in the order of DESIGN.md §4: faults due by now strike; working steered wheels
turn towards their commanded angle at most `steer_rate`·dt, the way that stays within their
steering limits (the stops: a target beyond them holds the wheel at the nearer stop, logged once
per wheel as a warning; twist commands never send one, `bots.chassis_commands`); driven wheels
follow their commanded speed through the motor model (clip, lag, acceleration limit); the body twist
is the core's least-squares forward kinematics of the driven wheels' rim speeds (a locked wheel
counts as 0, a free-running one not at all) together with the sliding constraints of fixed and
steered wheels, and its residual is the wheels' slip; the unobstructed motion over the step is the
exact `se2_exp(twist·dt)`. Passive wheels roll with the body; every wheel's encoder counts its own
rotation (quantised, remainder carried). The world then cuts the move at walls and robots as for any
robot. After the step, a second mouse sensor (if any) reads the body's true motion, and a wheel over
a hole drops the robot. The per-step wheel maths is one compiled kernel (`_wheels`, numba, like
`sim.world.kernels`); the least-squares matrices are rebuilt only when steering or faults change.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal, NamedTuple

import numba
import numpy as np

from sim.errors import UserError
from sim.kinematics import (
    counts_per_metre,
    mouse_displacement_from_increment,
    quantize,
    relative_increment,
)
from sim.kinematics.arc import wrap_angle
from sim.kinematics.batch import half_angle, quantize_one
from sim.kinematics.chassis import (
    STEER_SLACK,
    Chassis,
    Failure,
    WheelType,
    contact_velocities,
    degrade,
    forward_pinv,
    forward_system,
    rolling_rows,
    sliding_rows,
)
from sim.world.compiling import compiled_for
from sim.world.spec import FAULT_KINDS, WheelFault

if TYPE_CHECKING:
    from collections.abc import Sequence

    from bots.readings import Readings
    from sim.world.floor import FloorMap

FaultKind = Literal["lock", "free", "steering"]
_log = logging.getLogger(__name__)


class Motors(NamedTuple):
    """A chassis's motors and encoders (`_wheels`): each wheel's speed limit (rad/s), the lag
    (fraction of the way to the target per step), the acceleration limit (rad/s per step) and
    encoder ticks per wheel radian."""

    max_phi: np.ndarray
    lag: float
    max_change: float
    ticks_per_rad: float


class Wheels(NamedTuple):
    """A chassis's wheels over one step (`_wheels`), per wheel: speed (rad/s, in place), target
    speed, driven, locked, measured (the twist is solved from them), rim (m per rad of wheel) and
    this step's random slip (sqrt m)."""

    phi_dot: np.ndarray
    target_phi: np.ndarray
    driven: np.ndarray
    locked: np.ndarray
    measured: np.ndarray
    rim: np.ndarray
    slip: np.ndarray


class Solver(NamedTuple):
    """A chassis's forward kinematics at its wheels' angles (`_wheels`): A, pinv(A) and the
    rolling rows (what unmeasured wheels turn at)."""

    a: np.ndarray
    pinv: np.ndarray
    rolls: np.ndarray


class FaultError(UserError):
    """A fault that cannot strike (no such robot or wheel, a steering fault on an unsteered wheel)."""


@dataclass
class _Drive:
    """One chassis robot's drive state; `robot` is its `sim.world.physics.Robot`."""

    robot: Any
    nominal: Chassis
    steer_rate: float
    max_phi: np.ndarray
    lag: float
    max_change: float
    ticks_per_rad: float
    phi_dot: np.ndarray
    beta: np.ndarray
    target_phi: np.ndarray
    target_beta: np.ndarray
    tick_carry: np.ndarray
    ticks: np.ndarray
    failures: list[Failure] = field(default_factory=list)
    chassis: Chassis | None = None
    slip: float = 0.0
    twist: np.ndarray = field(default_factory=lambda: np.zeros(3))
    mouse2_carry: np.ndarray = field(default_factory=lambda: np.zeros(2))
    mouse2_counts: np.ndarray = field(default_factory=lambda: np.zeros(2, dtype=np.int64))
    _solver: tuple = ()
    _kernel: Any = None

    def __post_init__(self) -> None:
        self.chassis = self.nominal
        c = self.nominal
        self.stops = c.steer_max - c.steer_min < 2 * np.pi  # wheels with steering stops
        low, high = (np.where(self.stops, limit, 0.0) for limit in (c.steer_min, c.steer_max))
        self.steer_mid, self.steer_half = (low + high) / 2, np.where(self.stops, (high - low) / 2, np.inf)
        self.held: set[int] = set()  # wheels reported held at a stop
        self.passive = bool(np.isin(self.nominal.kind, (WheelType.CASTOR, WheelType.SPHERICAL)).any())
        self.rim = self.nominal.radius * np.cos(self.nominal.gamma)
        self.motors = Motors(self.max_phi, self.lag, self.max_change, self.ticks_per_rad)
        self._refresh()

    def _refresh(self) -> None:
        """What the current (degraded) chassis steers, drives, locks and measures, for every step."""
        c = self.chassis
        self.steerable = (c.kind == WheelType.STEERED) & c.steer_ok
        self.steers = bool(self.steerable.any())
        self.driven, self.locked = np.ascontiguousarray(c.driven, dtype=np.bool_), np.ascontiguousarray(c.locked, dtype=np.bool_)
        self.measured = self.driven | self.locked

    def strike(self, wheel: int, kind: FaultKind) -> None:
        """Apply a fault now; the core's `degrade` gives the new chassis state."""
        if not 0 <= wheel < self.nominal.n:
            raise FaultError(f"{self.robot.name} has wheels 0..{self.nominal.n - 1}, a fault names wheel {wheel}")
        if kind == "steering" and self.nominal.kind[wheel] != WheelType.STEERED:
            raise FaultError(f"{self.robot.name}: {self.nominal.names[wheel]} is not steered; its steering cannot fail")
        frozen = float(self.beta[wheel]) if kind in ("steering", "lock") else None
        failure = Failure(wheel, drive=kind == "free", steering=kind == "steering", frozen_beta=frozen,
                          locked=kind == "lock")
        if kind == "lock" and self.nominal.kind[wheel] == WheelType.STEERED:
            failure = Failure(wheel, steering=True, frozen_beta=frozen, locked=True)
        self.failures.append(failure)
        self.chassis = degrade(self.nominal.with_beta(self.beta), *self.failures)
        self._refresh()

    def step(self, dt: float, slip: np.ndarray) -> list[float]:
        """Steering, motors, forward kinematics and encoders for one step; the body increment (dx, dy, dθ)."""
        if self.steers:
            self._steer(self.steer_rate * dt)
        wheels = Wheels(self.phi_dot, self.target_phi, self.driven, self.locked, self.measured, self.rim, slip)
        arguments = (dt, self.motors, wheels, self._system(), self.tick_carry, self.ticks, self.twist)
        if self._kernel is None:  # (called without numba's dispatch, which types a NamedTuple in Python: a few µs a step)
            self._kernel = compiled_for(_wheels, *arguments)
        *increment, self.slip = self._kernel(*arguments)
        if self.passive:
            self._swivel(dt)
        return increment

    def _steer(self, max_turn: float) -> None:
        """Turn the working steered wheels towards their targets by at most `max_turn` rad. Headings are
        taken from the middle of each wheel's range, so that between two angles within the stops the
        wheel turns the way inside them (never through the gap of a range wider than π); a wheel that
        reaches its target takes it exactly. A target within the core's `STEER_SLACK` of a stop is
        within it (a tightest turn puts a wheel on its stop up to rounding)."""
        if not np.any(self.steerable & (self.beta != self.target_beta)):
            return  # every wheel at its target (the common case: steering settled)
        c = self.chassis
        offset = c.alpha - np.pi / 2 - self.steer_mid  # heading − middle of the range = β + offset
        now, wanted = wrap_angle(self.beta + offset), wrap_angle(self.target_beta + offset)
        goal = np.clip(wanted, -self.steer_half - STEER_SLACK, self.steer_half + STEER_SLACK)
        turn = np.where(self.stops, goal - now, wrap_angle(goal - now))
        beyond = self.steerable & (goal != wanted)
        for wheel in set(np.flatnonzero(beyond)) - self.held:
            self.held.add(wheel)
            _log.warning("%s: %s steered to %.1f°, beyond its stops %.1f°..%.1f°: held at the stop", self.robot.name,
                         c.names[wheel], math.degrees(wanted[wheel] + self.steer_mid[wheel]),
                         math.degrees(c.steer_min[wheel]), math.degrees(c.steer_max[wheel]))
        reached = np.abs(turn) <= max_turn
        moved = np.where(reached & ~beyond, self.target_beta, wrap_angle(now + np.clip(turn, -max_turn, max_turn) - offset))
        self.beta = np.where(self.steerable, wrap_angle(moved), self.beta)

    def _system(self) -> Solver:
        """A and pinv(A) of the forward kinematics and the rolling rows (what unmeasured wheels turn
        at), kept while β and the faults stay the same (C-ordered: the types `_wheels` was compiled for)."""
        key = (self.beta.tobytes(), len(self.failures))
        if not self._solver or self._solver[0] != key:
            c = self.chassis
            a, _ = forward_system(c, np.zeros(c.n), self.beta, self.measured)
            solver = Solver(*(np.ascontiguousarray(m, dtype=np.float64) for m in (a, forward_pinv(a), rolling_rows(c.alpha, self.beta, c.l, c.gamma))))
            self._solver = (key, solver)
        return self._solver[1]

    def _swivel(self, dt: float) -> None:
        """Passive wheels turn with the motion: castors by their swivel rate (2.51), balls to align."""
        c = self.chassis
        castor, ball = c.kind == WheelType.CASTOR, c.kind == WheelType.SPHERICAL
        if castor.any():
            d = np.where(castor, c.offset, 1.0)
            rate = -(sliding_rows(c.alpha, self.beta, c.l) @ self.twist + d * self.twist[2]) / d
            self.beta = np.where(castor, wrap_angle(self.beta + rate * dt), self.beta)
        if ball.any():
            v = contact_velocities(c, self.twist)
            moving = np.hypot(v[:, 0], v[:, 1]) > 1e-12
            aligned = wrap_angle(np.arctan2(v[:, 0], -v[:, 1]) - c.alpha)
            self.beta = np.where(ball & moving, aligned, self.beta)


class ChassisDrive:
    """The drives of all chassis robots of a world, with the fault schedule."""

    def __init__(self, dt: float) -> None:
        self.dt = dt
        self.drives: dict[int, _Drive] = {}
        self.schedule: list[WheelFault] = []

    def add(self, robot: Any) -> None:
        """Take over the drive of a world's `Robot` whose spec has a `chassis`."""
        spec = robot.spec
        chassis = spec.chassis.chassis
        motor = spec.motor
        limit = np.where(np.isfinite(chassis.max_speed), chassis.max_speed / chassis.radius, motor.max_wheel_speed)
        self.drives[robot.index] = _Drive(
            robot=robot, nominal=chassis, steer_rate=spec.chassis.steer_rate, max_phi=limit,
            lag=1.0 - math.exp(-self.dt / motor.time_constant) if motor.time_constant > 0 else 1.0,
            max_change=motor.max_acceleration * self.dt,
            ticks_per_rad=spec.encoders.ticks_per_rev / (2 * math.pi),
            phi_dot=np.zeros(chassis.n), beta=chassis.beta.copy(), target_phi=np.zeros(chassis.n),
            target_beta=chassis.beta.copy(), tick_carry=np.zeros(chassis.n), ticks=np.zeros(chassis.n, dtype=np.int64),
        )

    def schedule_faults(self, faults: list[WheelFault]) -> None:
        """Schedule faults, checked now: each must name a chassis robot, one of its wheels and a known kind."""
        for f in faults:
            drive = self.drives.get(f.robot)
            if drive is None:
                raise FaultError(f"a wheel fault names robot {f.robot}, which is not a robot on a general chassis")
            if f.kind not in FAULT_KINDS or not 0 <= f.wheel < drive.nominal.n:
                raise FaultError(f"a wheel fault of {drive.robot.name} names wheel {f.wheel} ({drive.nominal.n} wheels) "
                                 f"and kind {f.kind!r} ({', '.join(FAULT_KINDS)})")
            if f.kind == "steering" and drive.nominal.kind[f.wheel] != WheelType.STEERED:
                raise FaultError(f"{drive.robot.name}: {drive.nominal.names[f.wheel]} is not steered; its steering cannot fail")
        self.schedule = list(faults)

    def command(self, index: int, phi_dot: np.ndarray, beta: np.ndarray) -> None:
        """Set robot `index`'s wheel speed (rad/s) and wheel-plane angle (rad) targets, one per wheel."""
        drive = self.drives[index]
        phi_dot, beta = np.asarray(phi_dot, dtype=float), np.asarray(beta, dtype=float)
        n = drive.nominal.n
        if phi_dot.shape != (n,) or beta.shape != (n,):
            raise ValueError(f"{drive.robot.name}: expected {n} wheel speeds and {n} steering angles, "
                             f"got shapes {phi_dot.shape} and {beta.shape}")
        if not (np.all(np.isfinite(phi_dot)) and np.all(np.isfinite(beta))):
            raise ValueError(f"{drive.robot.name}: non-finite wheel command")
        drive.target_phi, drive.target_beta = np.ascontiguousarray(phi_dot), beta  # (C-ordered: the types `_wheels` was compiled for)

    def fail(self, index: int, wheel: int, kind: FaultKind) -> None:
        """Make a wheel of robot `index` fail now."""
        if kind not in FAULT_KINDS:
            raise FaultError(f"unknown fault kind {kind!r} (known: {', '.join(FAULT_KINDS)})")
        if index not in self.drives:
            raise FaultError(f"robot {index} has no general chassis; only its wheels can fail")
        self.drives[index].strike(wheel, kind)

    def drive(self, time: float, pose: np.ndarray, move: np.ndarray, alpha: np.ndarray) -> None:
        """Overwrite the planned world move (n, 2) and heading change (n,) of every chassis robot."""
        due = [f for f in self.schedule if f.time <= time + 1e-9 * self.dt]
        for fault in due:
            self.fail(fault.robot, fault.wheel, fault.kind)
            self.schedule.remove(fault)
        for i, drive in self.drives.items():
            slip = self._slip(drive)
            dx, dy, dtheta = drive.step(self.dt, slip)
            c, s = math.cos(pose[i, 2]), math.sin(pose[i, 2])
            move[i, 0], move[i, 1], alpha[i] = c * dx - s * dy, s * dx + c * dy, dtheta

    @staticmethod
    def _slip(drive: _Drive) -> np.ndarray:
        """Random slip of each wheel this step (EncoderSpec.slip_std, sqrt m; `_wheels` scales it by
        the rim's distance; tick_noise is a differential-drive model)."""
        enc = drive.robot.spec.encoders
        n = drive.nominal.n
        if not enc.slip_std:
            return np.zeros(n)
        return enc.slip_std * drive.robot.rngs["encoders"].standard_normal(n)

    def after_step(self, before: np.ndarray, after: np.ndarray, floor: FloorMap) -> None:
        """The second mouse reads the body's true motion (nothing over a hole)."""
        for i, drive in self.drives.items():
            mouse = drive.robot.spec.chassis.mouse2
            if mouse is None:
                continue
            increment = relative_increment(before[i], after[i])
            metres = mouse_displacement_from_increment(increment, np.asarray(mouse.mount))
            (mx, my), c, s = mouse.mount, math.cos(after[i, 2]), math.sin(after[i, 2])
            if floor.hole_at(after[i, 0] + c * mx - s * my, after[i, 1] + s * mx + c * my) or np.hypot(*metres) > mouse.max_speed * self.dt:
                metres = np.zeros(2)
            scale = counts_per_metre(mouse.dpi) * (1 + mouse.scale_error)
            if mouse.noise_std:  # (sqrt m: the variance grows with the floor passed, as the first mouse's)
                metres = metres + mouse.noise_std * math.sqrt(math.hypot(*metres)) * drive.robot.rngs["mouse2"].standard_normal(2)
            drive.mouse2_counts, drive.mouse2_carry = quantize(metres * scale, drive.mouse2_carry)

    def fill(self, readings: Sequence[Readings]) -> None:
        """Put each chassis robot's per-wheel ticks, steering angles, second mouse and faults into its readings."""
        for i, drive in self.drives.items():
            r = readings[i]
            r.encoder_ticks = drive.ticks.copy()
            r.steering = drive.beta.copy()
            r.mouse2_counts = drive.mouse2_counts.copy()
            r.failures = tuple(drive.failures)


@numba.njit(cache=True)
def _wheels(dt: float, motors: Motors, wheels: Wheels, solver: Solver, tick_carry: np.ndarray, ticks: np.ndarray, twist: np.ndarray) -> tuple[float, float, float, float]:
    """One chassis's wheels over one step, compiled (numpy's per-call cost dominated the step): driven
    wheels follow their targets through the motor model (clip, lag, acceleration limit), locked ones
    stop; the body twist is pinv(A)·b of the measured wheels' rim speeds (b's sliding half is 0) and
    the residual |A·twist − b| the slip; unmeasured wheels roll with the body; every encoder counts
    its rotation (`quantize_one`, remainder carried). Writes phi_dot, tick_carry, ticks and twist;
    returns the body increment `se2_exp(twist·dt)` (dx, dy, dθ; `half_angle` keeps dθ → 0
    continuous) and the slip (m/s)."""
    max_phi, lag, max_change, ticks_per_rad = motors
    phi_dot, target_phi, driven, locked, measured, rim, slip = wheels
    a, pinv, rolls = solver
    n = phi_dot.shape[0]
    rhs = np.zeros(a.shape[0])
    for i in range(n):
        if driven[i]:
            target = min(max(target_phi[i], -max_phi[i]), max_phi[i])
            phi_dot[i] += min(max((target - phi_dot[i]) * lag, -max_change), max_change)
        elif locked[i]:
            phi_dot[i] = 0.0
        if measured[i]:
            rim_speed = phi_dot[i] * rim[i]
            rhs[i] = rim_speed + slip[i] * math.sqrt(abs(rim_speed) / dt)  # arc off by slip * sqrt(|arc|)
    for k in range(3):
        total = 0.0
        for j in range(rhs.shape[0]):
            total += pinv[k, j] * rhs[j]
        twist[k] = total
    residual = 0.0
    for j in range(rhs.shape[0]):
        r = a[j, 0] * twist[0] + a[j, 1] * twist[1] + a[j, 2] * twist[2] - rhs[j]
        residual += r * r
    for i in range(n):
        if not measured[i]:
            phi_dot[i] = (rolls[i, 0] * twist[0] + rolls[i, 1] * twist[1] + rolls[i, 2] * twist[2]) / rim[i]
        whole, tick_carry[i] = quantize_one(phi_dot[i] * dt * ticks_per_rad + tick_carry[i])
        ticks[i] = int(whole)
    h = 0.5 * twist[2] * dt
    cos_h, sinc_h = half_angle(h)
    tx, ty = twist[0] * dt * sinc_h, twist[1] * dt * sinc_h
    return cos_h * tx - sinc_h * h * ty, sinc_h * h * tx + cos_h * ty, twist[2] * dt, math.sqrt(residual)

