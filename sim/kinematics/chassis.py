"""Kinematics of any wheeled chassis (Köb 2005, `chassis-koeb-thesis.md`; equation numbers are the thesis's).

A chassis is data: a frozen `Chassis` of per-wheel arrays for the five wheel types. From it come the
constraint matrices (J₁, J₂, C₁), the degree of mobility and steerability, the ICR of a twist and the
ICR locus of the chassis, the motion subspaces Z, S̄, S, B, D (what the planner may command, also after
failures), steering limits (which twists the steered wheels can point along, and the tightest turn
when they cannot), inverse kinematics (twist → steering angles and wheel speeds, with a typed refusal),
forward kinematics (wheel speeds → least-squares twist with the slip residual) and the kinetic torque
allocation for constraint-free chassis. A constant twist moves the body by `arc.se2_exp(twist·dt)`.

Conventions (DESIGN.md §3): SI units; body frame x forward, y left, angles CCW; a twist is
(v_x, v_y, ω) in the body frame at the reference point P, shape (..., 3). Wheel i sits at polar
(l, α) from P; β is its wheel-plane angle against the line P→wheel; its rolling direction (positive φ̇)
is u = (sin(α+β), −cos(α+β)), so its *heading* in the body frame is α + β − π/2.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from enum import IntEnum
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.kinematics.arc import wrap_angle

Array = NDArray[np.float64]

_RANK_TOL = 1e-9
"""Relative singular-value cut-off for ranks and null spaces (mixed m and rad units, so relative)."""


class WheelType(IntEnum):
    """The five wheel types of thesis 2.2.1.1."""

    FIXED = 0
    """Fixed standard wheel (2.46, 2.47): rolls along u, cannot slide along its axle."""
    STEERED = 1
    """Steered standard wheel, steering axis through the contact point (2.48, 2.49)."""
    CASTOR = 2
    """Passive castor with offset d (2.50, 2.51): never constrains the chassis."""
    OMNI = 3
    """Omni/Swedish wheel with roller angle γ (2.52); γ = ±π/4 is a Mecanum wheel."""
    SPHERICAL = 4
    """Ball wheel (2.54, 2.55): passive, β follows the motion."""


@dataclass(frozen=True)
class Wheel:
    """One wheel as data: type, mounting (l m, α rad), wheel-plane angle β (rad), radius r (m).

    `gamma` is the roller angle (OMNI only, |γ| < π/2), `offset` the castor offset d (CASTOR only, > 0).
    `driven` says whether the wheel has a working drive; `steer_ok` whether a STEERED wheel's
    steering works (if not, β stays frozen). `max_speed` is the rim-speed limit (m/s) and
    `steer_limits` the allowed heading range (rad, within [−π, π]) of a steered wheel: `check_steering`,
    `nearest_steerable` and `sim.kinematics.ocp` respect both.
    """

    kind: WheelType
    l: float
    alpha: float
    beta: float
    radius: float
    gamma: float = 0.0
    offset: float = 0.0
    driven: bool = True
    steer_ok: bool = True
    max_speed: float = np.inf
    steer_limits: tuple[float, float] = (-np.inf, np.inf)
    name: str = ""

    @classmethod
    def placed(cls, kind: WheelType, x: float, y: float, heading: float = 0.0, **kwargs) -> Wheel:
        """A wheel at body position (x, y) m whose rolling direction points along `heading` (rad)."""
        alpha = float(np.arctan2(y, x))
        return cls(kind, float(np.hypot(x, y)), alpha, float(wrap_angle(heading + np.pi / 2 - alpha)),
                   **kwargs)


_FIELDS = ("l", "alpha", "beta", "radius", "gamma", "offset", "max_speed")


@dataclass(frozen=True, eq=False)
class Chassis:
    """A wheeled chassis as per-wheel arrays of shape (n,); build it with `Chassis.from_wheels`.

    `beta` holds the current wheel-plane angles: fixed for FIXED and OMNI wheels, the current steering
    state for STEERED and CASTOR wheels (frozen after a steering failure), unused for SPHERICAL.
    `locked` marks seized wheels (see `Failure`).
    """

    kind: NDArray[np.int_]
    l: Array
    alpha: Array
    beta: Array
    radius: Array
    gamma: Array
    offset: Array
    driven: NDArray[np.bool_]
    steer_ok: NDArray[np.bool_]
    max_speed: Array
    steer_min: Array
    steer_max: Array
    names: tuple[str, ...] = field(default=())
    locked: NDArray[np.bool_] | None = None

    def __post_init__(self) -> None:
        n = len(self.kind)
        if self.locked is None:
            object.__setattr__(self, "locked", np.zeros(n, dtype=bool))
        for name in ("kind", *_FIELDS, "driven", "steer_ok", "steer_min", "steer_max", "locked"):
            value = np.array(getattr(self, name), dtype=int if name == "kind" else
                             bool if name in ("driven", "steer_ok", "locked") else float)
            if value.shape != (n,):
                raise ValueError(f"chassis field {name!r} has shape {value.shape}, expected ({n},)")
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        if not self.names:
            object.__setattr__(self, "names", tuple(f"wheel {i}" for i in range(n)))
        problems = []
        for i in range(n):
            kind = WheelType(self.kind[i])
            if not self.radius[i] > 0:
                problems.append(f"{self.names[i]}: radius must be > 0 m")
            if kind is WheelType.OMNI and not abs(self.gamma[i]) < np.pi / 2 - 1e-9:
                problems.append(f"{self.names[i]}: roller angle γ = ±π/2 is degenerate (2.52), need |γ| < π/2")
            if kind is not WheelType.OMNI and self.gamma[i] != 0:
                problems.append(f"{self.names[i]}: only omni wheels have a roller angle γ")
            if kind is WheelType.CASTOR and not self.offset[i] > 0:
                problems.append(f"{self.names[i]}: a castor needs offset d > 0 (d = 0 is a steered wheel)")
        if problems:
            raise ValueError("invalid chassis: " + "; ".join(problems))

    @classmethod
    def from_wheels(cls, wheels: Sequence[Wheel]) -> Chassis:
        """Stack `Wheel`s into a chassis."""
        return cls(
            kind=np.array([int(w.kind) for w in wheels], dtype=int),
            **{f: np.array([getattr(w, f) for w in wheels], dtype=float) for f in _FIELDS},
            driven=np.array([w.driven for w in wheels], dtype=bool),
            steer_ok=np.array([w.steer_ok for w in wheels], dtype=bool),
            steer_min=np.array([w.steer_limits[0] for w in wheels], dtype=float),
            steer_max=np.array([w.steer_limits[1] for w in wheels], dtype=float),
            names=tuple(w.name or f"wheel {i}" for i, w in enumerate(wheels)),
        )

    @property
    def n(self) -> int:
        """Number of wheels."""
        return len(self.kind)

    @property
    def positions(self) -> Array:
        """Wheel positions (n, 2) in the body frame (m) (2.99)."""
        return self.l[:, None] * np.stack([np.cos(self.alpha), np.sin(self.alpha)], axis=-1)

    @property
    def heading(self) -> Array:
        """Current rolling directions α + β − π/2 (n,) in the body frame (rad)."""
        return wrap_angle(self.alpha + self.beta - np.pi / 2)

    @property
    def fixed_like(self) -> NDArray[np.bool_]:
        """Wheels with a fixed plane that constrain the chassis: FIXED, and STEERED with frozen steering."""
        return (self.kind == WheelType.FIXED) | ((self.kind == WheelType.STEERED) & ~self.steer_ok)

    @property
    def steered_like(self) -> NDArray[np.bool_]:
        """Wheels whose β follows the motion: STEERED with working steering, and SPHERICAL (2.55)."""
        return ((self.kind == WheelType.STEERED) & self.steer_ok) | (self.kind == WheelType.SPHERICAL)

    def with_beta(self, beta: ArrayLike) -> Chassis:
        """The same chassis with new current wheel-plane angles (e.g. after steering)."""
        return replace(self, beta=np.broadcast_to(np.asarray(beta, dtype=float), (self.n,)))


# --- failures ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Failure:
    """A run-time fault of one wheel (thesis 2.2.2.2 table, notes 1-3).

    `drive`: the drive runs free (not locked): the wheel keeps its constraint but loses control.
    `steering`: a STEERED wheel's steering freezes at `frozen_beta` (rad; default: its current β),
    so it becomes a fixed wheel.
    `locked`: the wheel seizes (φ̇ = 0, and a steered wheel's steering with it): beyond the thesis
    (note 906), it adds its rolling row j·ξ = 0 as a constraint and loses its drive.
    """

    wheel: int
    drive: bool = False
    steering: bool = False
    frozen_beta: float | None = None
    locked: bool = False


def degrade(chassis: Chassis, *failures: Failure) -> Chassis:
    """The chassis after `failures` (a new `Chassis`; the original is unchanged)."""
    driven, steer_ok, beta = chassis.driven.copy(), chassis.steer_ok.copy(), chassis.beta.copy()
    locked = chassis.locked.copy()
    for f in failures:
        if not 0 <= f.wheel < chassis.n:
            raise ValueError(f"failure names wheel {f.wheel}, chassis has {chassis.n} wheels")
        if f.drive or f.locked:
            driven[f.wheel] = False
        if f.locked:
            locked[f.wheel] = True
            steer_ok[f.wheel] &= chassis.kind[f.wheel] != WheelType.STEERED
        if f.steering:
            if chassis.kind[f.wheel] != WheelType.STEERED:
                raise ValueError(f"{chassis.names[f.wheel]} is not a steered wheel; its steering cannot fail")
            steer_ok[f.wheel] = False
            if f.frozen_beta is not None:
                beta[f.wheel] = f.frozen_beta
    return replace(chassis, driven=driven, steer_ok=steer_ok, beta=beta, locked=locked)


# --- constraint rows and matrices -------------------------------------------------------------------


def rolling_rows(alpha: ArrayLike, beta: ArrayLike, l: ArrayLike, gamma: ArrayLike = 0.0) -> Array:
    """Rolling rows j = [sin(α+β+γ), −cos(α+β+γ), −l cos(β+γ)], shape (..., 3) (2.46, 2.52).

    j·ξ is the contact-point velocity along the wheel's driven direction; j·ξ = r φ̇ cos γ.
    """
    a, b, l, g = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (alpha, beta, l, gamma)))
    return np.stack([np.sin(a + b + g), -np.cos(a + b + g), -l * np.cos(b + g)], axis=-1)


def sliding_rows(alpha: ArrayLike, beta: ArrayLike, l: ArrayLike) -> Array:
    """Sliding rows c = [cos(α+β), sin(α+β), l sin β], shape (..., 3) (2.47): c·ξ = 0 means no side slip."""
    a, b, l = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (alpha, beta, l)))
    return np.stack([np.cos(a + b), np.sin(a + b), l * np.sin(b)], axis=-1)


def rolling_matrix(chassis: Chassis, beta: ArrayLike | None = None) -> Array:
    """J₁ (n, 3) at the current (or given) β, one rolling row per wheel (2.57, 2.58, 2.52).

    Unlike the thesis, every wheel keeps its row (castor and ball wheels roll too, 2.50, 2.54), so
    row i is wheel i; the *chassis* constraints are in `sliding_matrix`.
    """
    beta = chassis.beta if beta is None else np.asarray(beta, dtype=float)
    return rolling_rows(chassis.alpha, beta, chassis.l, chassis.gamma)


def radius_matrix(chassis: Chassis) -> Array:
    """J₂ = diag(r cos γ) (n, n), so that J₁ξ = J₂φ̇ (2.57; γ ≠ 0 from 2.52)."""
    return np.diag(chassis.radius * np.cos(chassis.gamma))


def sliding_matrix(chassis: Chassis, beta: ArrayLike | None = None) -> Array:
    """C₁ (n, 3) at the current (or given) β (2.59, 2.60): sliding rows of fixed and steered wheels, zero
    rows for castor, omni and ball wheels, which do not constrain the chassis."""
    beta = chassis.beta if beta is None else np.asarray(beta, dtype=float)
    constrains = np.isin(chassis.kind, (WheelType.FIXED, WheelType.STEERED))
    return sliding_rows(chassis.alpha, beta, chassis.l) * constrains[:, None]


def qualitative_matrices(chassis: Chassis) -> tuple[Array, Array]:
    """(J₁q, C₁q) of the thesis's table in 2.2.2.2, including failure states.

    A working steered wheel can push its contact point any way: two rolling rows (β = 0 and π/2) and no
    constraint (it is assumed aligned). A frozen one is a fixed wheel. A failed (free-running) or absent
    drive zeroes the wheel's rolling rows but keeps its constraint. Castor and ball wheels add nothing.
    A locked wheel adds its rolling row as one more constraint row (note 906).
    """
    j_rows, c_rows = [], []
    zero = np.zeros(3)
    for i in range(chassis.n):
        kind, driven = WheelType(chassis.kind[i]), bool(chassis.driven[i])
        a, b, l, g = chassis.alpha[i], chassis.beta[i], chassis.l[i], chassis.gamma[i]
        if chassis.fixed_like[i]:
            j_rows.append(rolling_rows(a, b, l) if driven else zero)
            c_rows.append(sliding_rows(a, b, l))
        elif kind is WheelType.STEERED:
            j_rows.extend(rolling_rows(a, [0.0, np.pi / 2], l) if driven else [zero, zero])
            c_rows.append(zero)
        elif kind is WheelType.OMNI:
            j_rows.append(rolling_rows(a, b, l, g) if driven else zero)
            c_rows.append(zero)
        else:
            j_rows.append(zero)
            c_rows.append(zero)
        if chassis.locked[i]:
            c_rows.append(rolling_rows(a, b, l, g))
    return np.array(j_rows, dtype=float).reshape(-1, 3), np.array(c_rows, dtype=float).reshape(-1, 3)


# --- subspaces ----------------------------------------------------------------------------------------


def _rank(m: Array) -> int:
    if m.size == 0:
        return 0
    s = np.linalg.svd(m, compute_uv=False)
    return int(np.sum(s > _RANK_TOL * max(1.0, s[0])))


def null_space(m: ArrayLike) -> Array:
    """Orthonormal basis (k, d) of Kern(m) for m of shape (rows, k), by SVD; (k, 0) if trivial."""
    m = np.atleast_2d(np.asarray(m, dtype=float))
    if m.size == 0:
        return np.eye(m.shape[1])
    _, _, vt = np.linalg.svd(m)
    return vt[_rank(m):].T


def projector(basis: ArrayLike) -> Array:
    """Orthogonal projector (k, k) onto span(basis columns): compares subspaces, not bases (§5.16)."""
    basis = np.asarray(basis, dtype=float)
    if basis.shape[1] == 0:
        return np.zeros((basis.shape[0], basis.shape[0]))
    q = null_space(null_space(basis.T).T)  # orthonormal basis of the span
    return q @ q.T


def _intersect(u: Array, w: Array) -> Array:
    """span(u) ∩ span(w) = Kern([u_⊥ᵀ; w_⊥ᵀ]); same result as the thesis's Zassenhaus run (2.88)."""
    return null_space(np.vstack([null_space(u.T).T, null_space(w.T).T]).reshape(-1, u.shape[0]))


@dataclass(frozen=True, eq=False)
class MotionSubspaces:
    """The thesis's motion subspaces (2.79-2.92), each an orthonormal basis (3, k) of twists.

    Z: admissible (no wheel slides). S̄ (`sbar`): uncontrollable (no driven wheel turns).
    S: controllable, the orthogonal complement of S̄. B: admissible and controllable, what the planner
    may command. D: admissible but uncontrollable, Z = B ⊕ D.
    """

    Z: Array
    sbar: Array
    S: Array
    B: Array
    D: Array


def motion_subspaces(chassis: Chassis) -> MotionSubspaces:
    """Z, S̄, S, B, D for the chassis's current state, failures included (2.79-2.92)."""
    j1q, c1q = qualitative_matrices(chassis)
    z, sbar = null_space(c1q), null_space(j1q)  # (2.79), (2.82)
    s = null_space(sbar.T)  # (2.86)
    if _rank(np.hstack([z, sbar])) == z.shape[1] + sbar.shape[1]:  # (2.84): Z ∩ S̄ = {0}
        b = z  # (2.85)
    else:
        b = _intersect(s, z)  # (2.88)
    d = _intersect(z, null_space(b.T))  # (2.91), (2.92)
    return MotionSubspaces(Z=z, sbar=sbar, S=s, B=b, D=d)


@dataclass(frozen=True)
class Mobility:
    """Degree of mobility δ_m, steerability δ_s and manoeuvrability δ_M = δ_m + δ_s (Siegwart, 2.2.2.1)."""

    mobility: int
    steerability: int

    @property
    def maneuverability(self) -> int:
        """δ_M = δ_m + δ_s."""
        return self.mobility + self.steerability


def mobility(chassis: Chassis) -> Mobility:
    """δ_m = 3 − rank C₁f − δ_s and δ_s = independent steering constraints a mobile chassis can use.

    Fixed wheels and frozen steered wheels form C₁f; working steered wheels add at most
    2 − rank C₁f constraints (more would immobilise the chassis). Failed drives do not change these.
    """
    fixed = chassis.fixed_like
    rank_f = _rank(sliding_rows(chassis.alpha[fixed], chassis.beta[fixed], chassis.l[fixed]))
    steer = (chassis.kind == WheelType.STEERED) & chassis.steer_ok
    # generic rank of C₁s: each steered wheel's sliding row ranges over [a, p×a] for all a
    generic = _rank(np.vstack([rolling_rows(chassis.alpha[steer], b, chassis.l[steer]) for b in (0, np.pi / 2)]))
    s = max(0, min(int(steer.sum()), generic, 2 - rank_f))
    return Mobility(mobility=max(0, 3 - rank_f - s), steerability=s)


# --- ICR ------------------------------------------------------------------------------------------------


def icr(twist: ArrayLike) -> Array:
    """Homogeneous ICR (..., 3) = (−v_y, v_x, ω) of a twist (2.97, 2.98).

    For ω ≠ 0 the ICR is the point (−v_y/ω, v_x/ω); for ω = 0 it lies at infinity in direction
    (−v_y, v_x). Scaled by the motion, it carries the whole twist: see `twist_from_icr`.
    """
    t = np.asarray(twist, dtype=float)
    return np.stack([-t[..., 1], t[..., 0], t[..., 2]], axis=-1)


def twist_from_icr(h: ArrayLike) -> Array:
    """The twist whose homogeneous ICR is h; for a finite ICR c and yaw rate ω, pass h = ω·(c_x, c_y, 1)."""
    h = np.asarray(h, dtype=float)
    return np.stack([h[..., 1], -h[..., 0], h[..., 2]], axis=-1)


@dataclass(frozen=True)
class IcrLocus:
    """Where the ICR of a chassis may lie, from its fixed-wheel axles (2.66-2.78, corrected criterion).

    kind: "anywhere" (no fixed wheels), "line" (normal·c = offset; includes the point at infinity,
    i.e. translation along `normal`), "point" (`point`), "infinity" (translation only, along
    `normal`), "immobile".
    """

    kind: Literal["anywhere", "line", "point", "infinity", "immobile"]
    point: Array | None = None
    normal: Array | None = None
    offset: float | None = None


def icr_locus(chassis: Chassis) -> IcrLocus:
    """Classify G·c = P (2.76-2.78) with the corrected uniqueness test rank G = 2 (erratum 9)."""
    fixed = chassis.fixed_like
    if not fixed.any():
        return IcrLocus("anywhere")
    g = rolling_rows(chassis.alpha[fixed], chassis.beta[fixed], 0.0)[:, :2]  # rows [sin(α+β), −cos(α+β)]
    p = chassis.l[fixed] * np.sin(chassis.beta[fixed])
    rank_g, rank_gp = _rank(g), _rank(np.column_stack([g, p]))
    if rank_g != rank_gp:
        return IcrLocus("infinity", normal=g[0]) if rank_g == 1 else IcrLocus("immobile")
    if rank_g == 2:
        return IcrLocus("point", point=np.linalg.lstsq(g, p, rcond=None)[0])
    return IcrLocus("line", normal=g[0], offset=float(p[0]))


# --- feasibility ----------------------------------------------------------------------------------------


class InfeasibleTwist(ValueError):
    """A twist the chassis cannot perform. `.nearest` is the nearest twist it can (projection onto B),
    `.mask` marks the infeasible entries of a batch."""

    def __init__(self, message: str, nearest: Array, mask: NDArray[np.bool_]):
        super().__init__(message)
        self.nearest = nearest
        self.mask = mask


def _tolerance(twist: Array) -> Array:
    return 1e-9 * (1.0 + np.linalg.norm(twist, axis=-1))


def nearest_feasible(chassis: Chassis, twist: ArrayLike) -> Array:
    """Orthogonal projection of twists (..., 3) onto span(B), the commandable twists (§2.6).

    Nearest in the Euclidean metric of (m/s, m/s, rad/s), the metric in which the thesis builds B.
    """
    twist = np.asarray(twist, dtype=float)
    return twist @ projector(motion_subspaces(chassis).B)


def is_feasible(chassis: Chassis, twist: ArrayLike) -> NDArray[np.bool_]:
    """Whether each twist (..., 3) lies in span(B) (admissible and controllable)."""
    twist = np.asarray(twist, dtype=float)
    return np.linalg.norm(twist - nearest_feasible(chassis, twist), axis=-1) <= _tolerance(twist)


def check_feasible(chassis: Chassis, twist: ArrayLike) -> None:
    """Raise `InfeasibleTwist`, saying why, if any twist (..., 3) lies outside span(B)."""
    twist = np.asarray(twist, dtype=float)
    nearest = nearest_feasible(chassis, twist)
    bad = np.linalg.norm(twist - nearest, axis=-1) > _tolerance(twist)
    if not bad.any():
        return
    example = twist[bad][0]
    slide = (np.abs(sliding_matrix(chassis) @ example) > _tolerance(example)) & chassis.fixed_like
    roll = (np.abs(rolling_matrix(chassis) @ example) > _tolerance(example)) & chassis.locked
    if slide.any() or roll.any():
        parts = [", ".join(chassis.names[i] for i in np.flatnonzero(slide)) + " slide sideways"] if slide.any() else []
        parts += [f"locked {chassis.names[i]} roll" for i in np.flatnonzero(roll)]
        why = "it would make " + " and ".join(parts)
    else:
        failed = [chassis.names[i] for i in range(chassis.n) if not chassis.driven[i]]
        why = ("no working drive can produce part of it (admissible but uncontrollable"
               + (f"; undriven: {', '.join(failed)})" if failed else ")"))
    raise InfeasibleTwist(
        f"{int(bad.sum())} of {bad.size} twists infeasible, e.g. {np.round(example, 6).tolist()}: {why}; "
        f"nearest feasible {np.round(nearest[bad][0], 6).tolist()}", nearest, bad)


# --- steering limits ------------------------------------------------------------------------------------

STEER_SLACK = 1e-9
"""rad: a heading exactly on its steering limit counts as within it, despite rounding."""


def _limited(chassis: Chassis) -> NDArray[np.bool_]:
    """Working steered wheels whose limits leave out some axle direction: with a range of π or more,
    every direction or its mirror lies within, so only narrower ranges restrict the chassis."""
    return ((chassis.kind == WheelType.STEERED) & chassis.steer_ok
            & (chassis.steer_max - chassis.steer_min < np.pi - STEER_SLACK))


def within_steering_limits(chassis: Chassis, heading: ArrayLike, *, mirror: bool = True) -> NDArray[np.bool_]:
    """Whether each wheel (..., n) can roll along `heading` (rad, body frame) within its steering limits:
    the heading itself or, with `mirror`, heading + π (the wheel turned round, rolling backwards)
    lies in [steer_min, steer_max]. True for wheels without (restricting) limits; `mirror=False`
    tests the heading alone, for every working steered wheel with finite limits."""
    heading = np.asarray(heading, dtype=float)
    if mirror:
        limited = _limited(chassis)
        period = np.pi
    else:
        limited = (chassis.kind == WheelType.STEERED) & chassis.steer_ok & (chassis.steer_max - chassis.steer_min < 2 * np.pi)
        period = 2 * np.pi
    low = np.where(limited, chassis.steer_min, 0.0)
    offset = np.mod(heading - low, period)  # [0, period): from the lower limit, counter-clockwise
    width = np.where(limited, chassis.steer_max - low, period)
    return ~limited | (offset <= width + STEER_SLACK) | (offset >= period - STEER_SLACK)


def _needed_headings(chassis: Chassis, twist: Array) -> tuple[Array, NDArray[np.bool_]]:
    """Headings (..., n) each wheel's contact point moves along for `twist`, and whether it moves at all
    (a steered wheel on the ICR may point anywhere)."""
    v_a = contact_velocities(chassis, twist)
    moving = np.hypot(v_a[..., 0], v_a[..., 1]) > _tolerance(twist)[..., None]
    return np.arctan2(v_a[..., 1], v_a[..., 0]), moving


def is_steerable(chassis: Chassis, twist: ArrayLike) -> NDArray[np.bool_]:
    """Whether each twist (..., 3) needs only steering angles within the limits of the working steered
    wheels, each wheel taking the angle or its mirror (β + π, rolling backwards). Feasibility in
    the sense of span(B) is `is_feasible`; a command must pass both."""
    twist = np.asarray(twist, dtype=float)
    heading, moving = _needed_headings(chassis, twist)
    return np.all(within_steering_limits(chassis, heading) | ~moving, axis=-1)


def nearest_steerable(chassis: Chassis, twist: ArrayLike) -> Array:
    """The steerable twist (..., 3) nearest to each twist in span(B) in the sense of driving: the
    tightest turn at the commanded speed.

    Steering limits bound how tight a turn is (a car's ICR must stay R_min from its rear axle's
    middle), not how fast; so the speed of the reference point P is kept and the rotation reduced:
    ξ + t·d for the least t ≥ 0 that is steerable, with d the translation of ξ (projected onto B),
    rescaled to the commanded speed at P. A rotation on the spot (no translation) keeps its yaw rate
    and gains the least forward speed instead (d = forward, projected onto B): a car asked to turn on
    the spot drives its tightest circle. t follows in closed form (a wheel's heading crosses a limit
    where its contact velocity, affine in t, crosses the limit's line). Twists already steerable come
    back unchanged; a twist for which no such t exists gives the zero twist (standing still).
    """
    twist = np.asarray(twist, dtype=float)
    flat = twist.reshape(-1, 3)
    return np.array([_nearest_steerable(chassis, t) for t in flat]).reshape(twist.shape)


def _nearest_steerable(chassis: Chassis, twist: Array) -> Array:
    if is_steerable(chassis, twist):
        return twist
    b = projector(motion_subspaces(chassis).B)
    moves = np.hypot(twist[0], twist[1]) > _tolerance(twist)
    direction = (np.array([twist[0], twist[1], 0.0]) if moves else np.array([1.0, 0.0, 0.0])) @ b
    limited = _limited(chassis)
    # contact velocities of the limited wheels: v(t) = v0 + t·dv, against the normals of both limit lines
    v0, dv = contact_velocities(chassis, twist)[limited], contact_velocities(chassis, direction)[limited]
    candidates = []
    for limit in (chassis.steer_min[limited], chassis.steer_max[limited]):
        normal = np.stack([-np.sin(limit), np.cos(limit)], axis=-1)
        a, slope = np.sum(normal * v0, axis=-1), np.sum(normal * dv, axis=-1)
        with np.errstate(divide="ignore", invalid="ignore"):
            candidates.extend((-a / slope)[slope != 0])
    for t in sorted(t for t in candidates if t > 0):
        moved = twist + t * direction
        if is_steerable(chassis, moved):
            keep = np.hypot(twist[0], twist[1]) / np.hypot(moved[0], moved[1]) if moves else abs(twist[2] / moved[2])
            return moved * keep
    return np.zeros(3)


def check_steering(chassis: Chassis, twist: ArrayLike) -> None:
    """Raise `InfeasibleTwist`, naming the wheels, the angles they would need and their limits, if any
    twist (..., 3) needs a steering angle (or its mirror) beyond a wheel's limits; `.nearest` is
    `nearest_steerable`."""
    twist = np.asarray(twist, dtype=float)
    heading, moving = _needed_headings(chassis, twist)
    outside = ~within_steering_limits(chassis, heading) & moving
    bad = np.any(outside, axis=-1)
    if not bad.any():
        return
    example, wheels, angles = twist[bad][0], outside[bad][0], heading[bad][0]
    deg = np.degrees
    why = "; ".join(
        f"{chassis.names[i]} would have to roll at {deg(angles[i]):.1f}° or {deg(wrap_angle(angles[i] + np.pi)):.1f}°, "
        f"beyond its steering limits {deg(chassis.steer_min[i]):.1f}°..{deg(chassis.steer_max[i]):.1f}°"
        for i in np.flatnonzero(wheels))
    nearest = nearest_steerable(chassis, twist)
    raise InfeasibleTwist(
        f"{int(bad.sum())} of {bad.size} twists beyond the steering limits, e.g. {np.round(example, 6).tolist()}: "
        f"{why}; tightest steerable turn {np.round(nearest[bad][0], 6).tolist()}", nearest, bad)


# --- inverse kinematics ---------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class WheelCommand:
    """Per-wheel set-points for a twist, arrays (..., n).

    beta: wheel-plane angles (rad; commands for working steered wheels, otherwise their current or
    resulting values); heading: rolling direction in the body frame (rad); phi_dot: signed wheel
    speeds (rad/s; for undriven wheels the speed they free-run at); rim_speed = r·φ̇ (m/s);
    beta_rate: castor swivel rate β̇ (rad/s, 0 for other wheels); at_icr: the ICR lies on this
    steered/ball wheel, so its β is undefined and kept from before (§5.10).
    """

    beta: Array
    heading: Array
    phi_dot: Array
    rim_speed: Array
    beta_rate: Array
    at_icr: NDArray[np.bool_]

    @property
    def rpm(self) -> Array:
        """Wheel speeds in revolutions per minute, N = 60/(2π)·φ̇ (2.117)."""
        return self.phi_dot * 60 / (2 * np.pi)


def contact_velocities(chassis: Chassis, twist: ArrayLike) -> Array:
    """Velocity (..., n, 2) of each wheel's mounting point: v_A = (ẋ − θ̇ l sin α, ẏ + θ̇ l cos α) (2.93)."""
    t = np.asarray(twist, dtype=float)[..., None, :]
    p = chassis.positions
    return np.stack([t[..., 0] - t[..., 2] * p[:, 1], t[..., 1] + t[..., 2] * p[:, 0]], axis=-1)


def inverse_kinematics(
    chassis: Chassis,
    twist: ArrayLike,
    *,
    previous_beta: ArrayLike | None = None,
    branch: Literal["nearest", "forward"] = "nearest",
) -> WheelCommand:
    """Steering angles and signed wheel speeds for twists (..., 3) (2.99-2.117, singularity-free form).

    Steered and ball wheels point along their contact velocity (β = atan2(v_Ax, −v_Ay) − α, equivalent
    to the ICR method (2.103)/(2.106) without its ω = 0 branch). Of the two equivalent settings (β, v)
    and (β + π, −v), `branch="nearest"` takes the one within the wheel's steering limits, or if both
    (or neither) are, the one closest to `previous_beta` (default: the chassis's current β), avoiding
    π slews (2.2.6); `"forward"` always rolls forwards (v ≥ 0). Every wheel's speed
    is then its rolling row: φ̇ = j(β)·ξ / (r cos γ) (2.80, 2.116). Raises `InfeasibleTwist` for a twist
    outside span(B); steering limits are the caller's (`check_steering`: OCP maps them as blocked).
    """
    twist = np.asarray(twist, dtype=float)
    check_feasible(chassis, twist)
    prev = chassis.beta if previous_beta is None else np.asarray(previous_beta, dtype=float)
    v_a = contact_velocities(chassis, twist)
    speed = np.hypot(v_a[..., 0], v_a[..., 1])
    at_icr = chassis.steered_like & (speed <= _tolerance(twist)[..., None])
    aligned = wrap_angle(np.arctan2(v_a[..., 0], -v_a[..., 1]) - chassis.alpha)
    if branch == "nearest":
        flip = np.abs(wrap_angle(aligned - prev)) > np.pi / 2
        heading = chassis.alpha + aligned - np.pi / 2
        fits = within_steering_limits(chassis, heading, mirror=False)
        fits_flipped = within_steering_limits(chassis, heading + np.pi, mirror=False)
        flip = np.where(fits == fits_flipped, flip, fits_flipped)  # a steering limit overrules nearness
        aligned = np.where(flip, wrap_angle(aligned + np.pi), aligned)
    beta = np.where(chassis.steered_like & ~at_icr, aligned, prev)
    phi_dot = np.einsum("...ij,...j->...i", rolling_rows(chassis.alpha, beta, chassis.l, chassis.gamma), twist)
    phi_dot = phi_dot / (chassis.radius * np.cos(chassis.gamma))
    castor = chassis.kind == WheelType.CASTOR
    offset = np.where(castor, chassis.offset, 1.0)
    c_castor = sliding_rows(chassis.alpha, beta, chassis.l) + np.stack(
        [np.zeros(chassis.n), np.zeros(chassis.n), offset], axis=-1)
    beta_rate = np.where(castor, -np.einsum("...ij,...j->...i", c_castor, twist) / offset, 0.0)  # (2.51)
    return WheelCommand(beta=beta, heading=wrap_angle(chassis.alpha + beta - np.pi / 2), phi_dot=phi_dot,
                        rim_speed=phi_dot * chassis.radius, beta_rate=beta_rate, at_icr=at_icr)


# --- forward kinematics ---------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class ForwardSolution:
    """Least-squares twist (..., 3) from wheel speeds, with residuals (m/s) saying how much the wheels
    fight each other: `rolling` (..., n) per measured wheel, `sliding` (..., n) per fixed/steered wheel.
    `rank` < 3 means the wheels do not determine the twist (minimum-norm solution returned)."""

    twist: Array
    rolling: Array
    sliding: Array
    rank: NDArray[np.int_]

    @property
    def slip(self) -> Array:
        """Root-sum-square of all residuals (m/s); 0 for wheels that agree on one rigid motion."""
        return np.sqrt(np.sum(self.rolling**2, axis=-1) + np.sum(self.sliding**2, axis=-1))


def forward_system(chassis: Chassis, phi_dot: ArrayLike, beta: ArrayLike,
                   measured: ArrayLike | None = None) -> tuple[Array, Array]:
    """The stacked equations A ξ = b (m/s) of `forward_kinematics`: A (..., 2n, 3) holds the rolling rows
    of the measured wheels (zero rows for the others), then the sliding rows of fixed and steered wheels;
    b (..., 2n) the measured rim speeds r φ̇ cos γ, then zeros. The least-squares twist is pinv(A)·b."""
    phi_dot, beta = np.asarray(phi_dot, dtype=float), np.asarray(beta, dtype=float)
    use = np.ones(chassis.n, bool) if measured is None else np.asarray(measured, dtype=bool)
    constrains = np.isin(chassis.kind, (WheelType.FIXED, WheelType.STEERED))
    roll = rolling_rows(chassis.alpha, beta, chassis.l, chassis.gamma) * use[:, None]
    slide = sliding_rows(chassis.alpha, beta, chassis.l) * constrains[:, None]
    rhs = np.concatenate([phi_dot * chassis.radius * np.cos(chassis.gamma) * use, np.zeros_like(phi_dot)], axis=-1)
    return np.concatenate([roll, slide], axis=-2), rhs


def forward_pinv(a: ArrayLike) -> Array:
    """pinv(A) with the core's rank cut-off, for reusing one `forward_system` matrix over many steps."""
    return np.linalg.pinv(np.asarray(a, dtype=float), rcond=_RANK_TOL)


def forward_kinematics(
    chassis: Chassis,
    phi_dot: ArrayLike,
    beta: ArrayLike | None = None,
    measured: ArrayLike | None = None,
) -> ForwardSolution:
    """Twist from wheel speeds φ̇ (..., n) rad/s and wheel-plane angles β (..., n): least squares of the
    rolling constraints J₁ξ = J₂φ̇ of the `measured` wheels (default all) together with the sliding
    constraints C₁ξ = 0 of fixed and steered wheels (2.57, 2.59; thesis §2.10: ξ = (J₂⁻¹J₁)⁺φ̇).
    All equations are in m/s, so wheels of different radius weigh alike.
    """
    phi_dot, beta = np.broadcast_arrays(np.asarray(phi_dot, dtype=float),
                                        chassis.beta if beta is None else np.asarray(beta, dtype=float))
    a, rhs = forward_system(chassis, phi_dot, beta, measured)
    twist = np.einsum("...ij,...j->...i", forward_pinv(a), rhs)
    residual = np.einsum("...ij,...j->...i", a, twist) - rhs
    rank = np.linalg.matrix_rank(a, tol=None)
    return ForwardSolution(twist=twist, rolling=residual[..., : chassis.n], sliding=residual[..., chassis.n:],
                           rank=np.asarray(rank))


# --- kinetic torque allocation ----------------------------------------------------------------------------


def allocation_matrix(chassis: Chassis) -> Array:
    """A (3, n) with F_R = A·M (2.13, 2.14): column i = j_iᵀ/(r_i cos γ_i) for a working drive, else 0.

    Only for chassis without kinematic constraints (omni, castor and ball wheels): with fixed or
    steered wheels the contact forces do not follow from the drive torques alone (2.1.6). The
    reference point must be the centre of mass.
    """
    if np.isin(chassis.kind, (WheelType.FIXED, WheelType.STEERED)).any():
        raise ValueError("torque allocation (2.13) needs a chassis without fixed or steered wheels")
    driven = chassis.driven & (chassis.kind == WheelType.OMNI)
    return (rolling_matrix(chassis) / (chassis.radius * np.cos(chassis.gamma))[:, None] * driven[:, None]).T


@dataclass(frozen=True, eq=False)
class TorqueAllocation:
    """Drive torques M (..., n) (Nm) for a wrench F_R, the wrench they achieve (A M), and rank A.

    rank 3: every wrench is achieved exactly (2.17). Otherwise `achieved` is the projection of the
    request onto range(A) and `residual` = ‖A M − F_R‖ says how far off it is (§3.1(c))."""

    torques: Array
    achieved: Array
    residual: Array
    rank: int


def allocate_torques(chassis: Chassis, wrench: ArrayLike) -> TorqueAllocation:
    """M = A⁺F_R with the SVD pseudoinverse (2.16; erratum 1: (AᵀA)⁻¹Aᵀ is singular for n > 3)."""
    a = allocation_matrix(chassis)
    wrench = np.asarray(wrench, dtype=float)
    torques = wrench @ np.linalg.pinv(a, rcond=_RANK_TOL).T
    achieved = torques @ a.T
    return TorqueAllocation(torques=torques, achieved=achieved,
                            residual=np.linalg.norm(achieved - wrench, axis=-1), rank=_rank(a))


# --- frames ------------------------------------------------------------------------------


def to_world(theta: ArrayLike, twist: ArrayLike) -> Array:
    """Body twist → inertial-frame velocity ξ̇_I = R(θ)ᵀ ξ̇_R (1.5, 1.6)."""
    theta, t = np.asarray(theta, dtype=float), np.asarray(twist, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([c * t[..., 0] - s * t[..., 1], s * t[..., 0] + c * t[..., 1], t[..., 2]], axis=-1)


def to_body(theta: ArrayLike, velocity: ArrayLike) -> Array:
    """Inertial-frame velocity → body twist ξ̇_R = R(θ) ξ̇_I (1.3, 1.4)."""
    return to_world(-np.asarray(theta, dtype=float), velocity)
