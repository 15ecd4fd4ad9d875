"""Omni-Curve-Parameters (Brenner & Colomb; `omni-curve-parameters.md`, sections cited as "OCP §x").

An OCP command is (κ_n, β, v_s): nominal curvature κ_n ∈ [−2, 2] (0 straight, |κ_n| < 1 soft curves
linear in curvature, 1 ≤ |κ_n| ≤ 2 sharp curves linear in radius, ±2 turning on the spot), float angle
β (rad, direction of the reference point's velocity in the body frame) and speed scalar
v_s = v_n·v_max (m/s). Two chassis constants: the limit curvature κ_g (1/m) and v_max (m/s).

This module maps OCP ↔ twist ↔ ICR, derives κ_g and v_max from a `Chassis`, turns OCP into per-wheel
set-points through the chassis's inverse kinematics, and samples the permissible configuration space
over (κ_n, β) with actuator limits (rim speed, steering angle): the vehicle's motion "data sheet".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.kinematics.arc import wrap_angle
from sim.kinematics.chassis import (
    Chassis,
    InfeasibleTwist,
    WheelCommand,
    WheelType,
    icr,
    inverse_kinematics,
    is_feasible,
    nearest_feasible,
    twist_from_icr,
)

Array = NDArray[np.float64]


def sgn(x: ArrayLike) -> Array:
    """The paper's signum without zero: +1 for x ≥ 0 (also −0.0), −1 for x < 0 (OCP §0)."""
    return np.where(np.asarray(x, dtype=float) >= 0, 1.0, -1.0)


def rho_from_kappa_n(kappa_n: ArrayLike) -> Array:
    """Dimensionless curvature ρ = κ/κ_g: κ_n on the soft branch, 1/(2 sgn κ_n − κ_n) on the sharp one
    (OCP §2.1); ±∞ at κ_n = ±2."""
    kn = np.asarray(kappa_n, dtype=float)
    with np.errstate(divide="ignore"):
        return np.where(np.abs(kn) < 1, kn, sgn(kn) / (2 - np.abs(kn)))


def kappa_n_from_rho(rho: ArrayLike) -> Array:
    """Inverse of `rho_from_kappa_n`: κ_n = ρ for |ρ| < 1, sgn ρ·(2 − 1/|ρ|) otherwise (OCP §2.1)."""
    rho = np.asarray(rho, dtype=float)
    with np.errstate(divide="ignore"):
        return np.where(np.abs(rho) < 1, rho, sgn(rho) * (2 - 1 / np.abs(rho)))


def ocp_to_twist(kappa_n: ArrayLike, beta: ArrayLike, v_s: ArrayLike, kappa_g: float) -> Array:
    """Body twist (..., 3) at the reference point K (OCP §2.1, §5.1), never forming ∞:

    soft  (|κ_n| < 1):  v_s·(cos β, sin β, κ_g κ_n)
    sharp (|κ_n| ≥ 1):  v_s·((2 − |κ_n|) cos β, (2 − |κ_n|) sin β, κ_g sgn κ_n)
    """
    kn, beta, v_s = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (kappa_n, beta, v_s)))
    if np.any(np.abs(kn) > 2 + 1e-12):
        raise ValueError(f"nominal curvature κ_n must lie in [−2, 2], got {kn[np.abs(kn) > 2 + 1e-12][0]}")
    soft = np.abs(kn) < 1
    speed = v_s * np.where(soft, 1.0, 2 - np.abs(kn))
    omega = v_s * kappa_g * np.where(soft, kn, sgn(kn))
    return np.stack([speed * np.cos(beta), speed * np.sin(beta), omega], axis=-1)


def ocp_icr(kappa_n: ArrayLike, beta: ArrayLike, kappa_g: float) -> Array:
    """Homogeneous ICR (..., 3) of the OCP configuration (OCP §5.1), i.e. of its unit-speed motion.

    The ICR itself (h_x/h_ω, h_y/h_ω), or its direction at infinity for κ_n = 0, does not depend on v_s.
    """
    return icr(ocp_to_twist(kappa_n, beta, 1.0, kappa_g))


def twist_to_ocp(
    twist: ArrayLike,
    kappa_g: float,
    *,
    convention: Literal["forward", "continuity", "line"] = "forward",
    beta_prev: ArrayLike = 0.0,
    kappa_prev: ArrayLike = 0.0,
    beta0: float = 0.0,
    tol: float = 1e-12,
) -> tuple[Array, Array, Array]:
    """(κ_n, β, v_s) of twists (..., 3) (OCP §5.2).

    The mirror ambiguity (κ_n, β, v_s) ~ (−κ_n, β ± π, −v_s) is resolved by `convention`:
    "forward" (holonomic): β = direction of travel, v_s ≥ 0;
    "continuity" (holonomic): of the two, the β nearest `beta_prev`;
    "line" (line-mobile chassis): β ≡ `beta0`, v_s signed; a twist with velocity across β0 raises
    `InfeasibleTwist`.
    At standstill (v = ω = 0) the previous configuration (`kappa_prev`, `beta_prev`) is kept with
    v_s = 0; in a spot turn β is free and kept from `beta_prev`.
    """
    t = np.asarray(twist, dtype=float)
    vx, vy, omega = t[..., 0], t[..., 1], t[..., 2]
    beta_prev = np.broadcast_to(np.asarray(beta_prev, dtype=float), vx.shape)
    speed = np.hypot(vx, vy)
    if convention == "line":
        along = np.cos(beta0) * vx + np.sin(beta0) * vy
        across = -np.sin(beta0) * vx + np.cos(beta0) * vy
        bad = np.abs(across) > tol * (1 + speed)
        if bad.any():
            nearest = np.stack([along * np.cos(beta0), along * np.sin(beta0), omega], axis=-1)
            raise InfeasibleTwist(
                f"a line-mobile chassis moves only along β0 = {beta0:.6g} rad, but {int(bad.sum())} twists have "
                f"lateral velocity (e.g. {across[bad][0]:.6g} m/s); nearest feasible "
                f"{np.round(nearest[bad][0], 6).tolist()}", nearest, bad)
        v, beta = along, np.full_like(along, beta0)
    else:
        beta = np.arctan2(vy, vx)
        v = speed
        if convention == "continuity":
            flip = np.abs(wrap_angle(beta - beta_prev)) > np.pi / 2
            beta, v = np.where(flip, wrap_angle(beta + np.pi), beta), np.where(flip, -speed, speed)
        beta = np.where(speed > tol, beta, beta_prev)  # spot turn or standstill: β is free
    v = np.where(np.abs(v) <= tol * (1 + np.abs(omega)), 0.0, v)  # rounding must not reverse a spot turn
    sigma = sgn(v)
    v_s = sigma * np.maximum(np.abs(v), np.abs(omega) / kappa_g)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        soft = np.abs(omega) < kappa_g * np.abs(v)
        kappa_n = np.where(soft, omega / (kappa_g * v), sgn(omega) * sigma * (2 - kappa_g * np.abs(v) / np.abs(omega)))
    still = (speed <= tol) & (np.abs(omega) <= tol)
    kappa_n = np.where(still, np.broadcast_to(np.asarray(kappa_prev, dtype=float), vx.shape), kappa_n)
    return kappa_n, beta, np.where(still, 0.0, v_s)


def icr_to_ocp(h: ArrayLike, kappa_g: float, **kwargs) -> tuple[Array, Array, Array]:
    """(κ_n, β, v_s) from a homogeneous ICR scaled by the motion, h = ω·(c_x, c_y, 1) for a finite ICR c
    (OCP §5.3); keyword arguments as for `twist_to_ocp`."""
    return twist_to_ocp(twist_from_icr(h), kappa_g, **kwargs)


# --- chassis constants ------------------------------------------------------------------------------


def _limited(chassis: Chassis) -> NDArray[np.bool_]:
    """Wheels whose rolling speed the OCP limits: fixed, steered and omni wheels (not passive supports)."""
    return np.isin(chassis.kind, (WheelType.FIXED, WheelType.STEERED, WheelType.OMNI))


def kappa_g_for(chassis: Chassis) -> float:
    """κ_g = 1/|w_k| for the wheel k with the largest |w_i|/u_lim,i (OCP §2.2, paper §3.2).

    Wheels without a speed limit do not count; with no limits at all, or any omni/Mecanum wheel, the
    longest |w_i| decides. Differential drive: 2/b; single-track Ackermann: 1/a.
    """
    keep = _limited(chassis)
    dist = np.hypot(*chassis.positions[keep].T)
    ratio = dist / chassis.max_speed[keep]
    if (chassis.kind == WheelType.OMNI).any() or not np.any(ratio > 0):
        ratio = dist
    return float(1 / dist[np.argmax(ratio)])


def v_max_for(chassis: Chassis) -> float:
    """Default constant v_max = min u_lim,i over driven wheels: pure translation uses the slowest one fully."""
    return float(np.min(chassis.max_speed[chassis.driven & _limited(chassis)], initial=np.inf))


# --- wheel set-points and configuration space ---------------------------------------------------------------


def wheel_setpoints(chassis: Chassis, kappa_n: ArrayLike, beta: ArrayLike, v_s: ArrayLike,
                    kappa_g: float) -> WheelCommand:
    """Per-wheel set-points (steering, signed wheel speeds) for OCP commands, for any chassis (OCP §2.4).

    The configuration fixes the steering (also at v_s = 0, so a vehicle can pre-steer); v_s only scales
    the speeds, whose sign follows v_s for steered wheels (the paper's atan2 form: α_i = atan2(d_i)).
    Fixed wheels get signed speeds, omni and Mecanum wheels their roller-projected speeds. Raises
    `InfeasibleTwist` for a configuration the chassis cannot drive.
    """
    unit = inverse_kinematics(chassis, ocp_to_twist(kappa_n, beta, 1.0, kappa_g), branch="forward")
    v_s = np.asarray(v_s, dtype=float)[..., None]
    return WheelCommand(beta=unit.beta, heading=unit.heading, phi_dot=unit.phi_dot * v_s,
                        rim_speed=unit.rim_speed * v_s, beta_rate=unit.beta_rate * v_s, at_icr=unit.at_icr)


@dataclass(frozen=True, eq=False)
class Configurations:
    """The permissible configuration space sampled at (κ_n, β) points of shape S (OCP §3.5, §3.7).

    heading (S + (n,)): wheel headings α_i (rad, in (−π, π]); rim_speed (S + (n,)): u_i at v_s = 1 (m/s);
    blocked (S): a steering limit, the singular neighbourhood of a steered wheel, or the chassis's
    kinematics forbids the configuration; v_max (S): fastest v_s there (m/s), 0 where blocked.
    """

    kappa_n: Array
    beta: Array
    heading: Array
    rim_speed: Array
    blocked: NDArray[np.bool_]
    v_max: Array


def ocp_grid(n_kappa: int = 161, n_beta: int = 361) -> tuple[Array, Array]:
    """A (κ_n, β) mesh (n_kappa, n_beta): κ_n over [−2, 2] (n_kappa = 4m + 1 keeps 0, ±1, ±2 as nodes),
    β over [−π, π], both ends included."""
    return np.meshgrid(np.linspace(-2, 2, n_kappa), np.linspace(-np.pi, np.pi, n_beta), indexing="ij")


def configuration_space(
    chassis: Chassis,
    kappa_n: ArrayLike,
    beta: ArrayLike,
    *,
    kappa_g: float | None = None,
    margin: float = 0.0,
    v_cap: float = np.inf,
) -> Configurations:
    """Evaluate configurations (κ_n, β) (broadcast arrays) against the actuator limits (OCP §3.7).

    A configuration is blocked if a working steered wheel's heading leaves its steering limits
    (OCP §3.2: the branch reached from the zero position, α_i = atan2(d_i) ∈ (−π, π]), if the ICR lies
    within `margin` metres of a steered wheel (§3.3; at margin 0 only exactly on it), or if the
    chassis cannot perform the motion at all (e.g. β ≠ 0 on a line-mobile chassis).
    v_max = min_i u_lim,i / |u_i| over wheels with a finite limit (§3.4), capped by `v_cap`.
    """
    kappa_g = kappa_g_for(chassis) if kappa_g is None else kappa_g
    kn, beta = np.broadcast_arrays(np.asarray(kappa_n, dtype=float), np.asarray(beta, dtype=float))
    unit = ocp_to_twist(kn, beta, 1.0, kappa_g)
    possible = is_feasible(chassis, unit)
    cmd = inverse_kinematics(chassis, nearest_feasible(chassis, unit), branch="forward")
    steered = (chassis.kind == WheelType.STEERED) & chassis.steer_ok
    slack = 1e-9  # rad: a heading exactly on its limit is allowed despite rounding
    outside = steered & ((cmd.heading < chassis.steer_min - slack) | (cmd.heading > chassis.steer_max + slack))
    with np.errstate(divide="ignore", invalid="ignore"):
        distance = np.abs(cmd.rim_speed) / np.abs(unit[..., 2:3])  # |u_i| = |ω|·|p_i|
        ratio = np.where(np.abs(cmd.rim_speed) > 1e-12, chassis.max_speed / np.abs(cmd.rim_speed), np.inf)
    singular = chassis.steered_like & (cmd.at_icr | (distance < margin))
    blocked = ~possible | np.any(outside | singular, axis=-1)
    v_max = np.where(blocked, 0.0, np.minimum(np.min(ratio, axis=-1), v_cap))
    return Configurations(kappa_n=kn, beta=beta, heading=cmd.heading, rim_speed=cmd.rim_speed,
                          blocked=blocked, v_max=v_max)
