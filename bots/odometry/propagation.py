"""The error models every default estimator shares and their propagation, compiled: an
increment's Jacobian on the calibration errors and its noise (`wheel_terms`, `mouse_terms`), the
random variances the believed noise gives a step (`wheel_variances`, `mouse_variance`), the
covariance carried through laying an arc (`propagate`), and the reported pose covariance with the
quantisation lag and the sigma points' spread (`pose_covariance`, `add_spread`), and the random
part carried along each sigma point's own path (`lay_point`, `add_point_noise`).

Each estimator's own compiled step lives in its file (`encoder`, `mouse`, `fused`) and calls
these. numba caches a kernel by its own file's content: a change here recompiles its callers
because this module is one of `sim.kernel_cache.SHARED`.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from bots.odometry.layout import MOUSE_NODE_WEIGHTS, MOUSE_SIGMAS, NODE_WEIGHTS, PLANE, SIGMAS
from bots.uncertainty import ERROR, ERRORS
from sim.kinematics.batch import INNER, advance_one

MID_ANGLE, END_HEADING = 0.5, 1.0
"""Where an arc's chord is laid (`propagate`'s share of the heading change): along the mid-angle
(exact, seed 002 eqs 1.7, 1.12) or along the end heading (the c't-Bot firmware)."""


@numba.njit(cache=True, error_model="numpy")
def wheel_terms(s_left: float, s_right: float, alpha: float, track: float, var_left: float, var_right: float,
                jac: np.ndarray, noise: np.ndarray) -> None:  # fmt: skip
    """The encoder increment's error model, in place: `jac` (2, ERRORS) of (s, alpha) on the
    scales for wheel arcs s_left, s_right (m) and heading change alpha over `track` (m); `noise`
    (2, 2) for independent wheel-arc variances var_left, var_right (m²)."""
    jac[:, :] = 0.0
    jac[0, ERROR.left_scale], jac[0, ERROR.right_scale] = 0.5 * s_left, 0.5 * s_right
    jac[1, ERROR.left_scale], jac[1, ERROR.right_scale], jac[1, ERROR.track_scale] = -s_left / track, s_right / track, -alpha
    noise[0, 0] = 0.25 * (var_left + var_right)
    noise[0, 1] = noise[1, 0] = 0.5 * (var_right - var_left) / track
    noise[1, 1] = (var_left + var_right) / (track * track)


@numba.njit(cache=True, error_model="numpy")
def mouse_terms(s: float, alpha: float, mount_x: float, mount_y: float, var: float, jac: np.ndarray, noise: np.ndarray) -> None:
    """The mouse increment's error model, in place: `jac` on the resolution's error for the
    increment (s m, alpha rad), `noise` for a variance `var` (m²) of each axis's reading, through
    alpha = lateral/m_x, s = forward + alpha*m_y."""
    jac[:, :] = 0.0
    jac[0, ERROR.mouse_scale], jac[1, ERROR.mouse_scale] = -s, -alpha
    lever = mount_y / mount_x
    noise[0, 0] = var * (1.0 + lever * lever)
    noise[0, 1] = noise[1, 0] = var * lever / mount_x
    noise[1, 1] = var / (mount_x * mount_x)


@numba.njit(cache=True, error_model="numpy", **INNER)
def propagate(cov: np.ndarray, heading: float, s: float, alpha: float, share: float, jac: np.ndarray, noise: np.ndarray,
              work: np.ndarray) -> None:  # fmt: skip
    """`cov` (ERRORS, ERRORS) after laying the increment (s, alpha) from `heading` (rad, before
    the step) along `heading + share * alpha` (`MID_ANGLE`, exact, or `END_HEADING`, the
    firmware), whose error is jac @ errors + n, n ~ noise: cov <- A cov A^T + G noise G^T, with A
    the identity but for the pose rows (d pose'/d pose and G @ jac, G = d pose'/d (s, alpha)).
    `work` (WORK, ERRORS, ERRORS): scratch planes (`workspace`), its PLANE.propagate_* used.
    (A float, not a bool: numba compiles a function once for each constant bool it is called with.)"""
    angle = heading + share * alpha
    c, sn = math.cos(angle), math.sin(angle)
    lever = share * s
    g = ((c, -lever * sn), (sn, lever * c), (0.0, 1.0))
    a, rows, pose = work[PLANE.propagate_a, :3], work[PLANE.propagate_rows, :3], work[PLANE.propagate_pose, :3, :3]  # rows: a @ cov; pose: a @ cov @ a^T, + G noise G^T
    a[:, :] = 0.0
    for r in range(3):
        a[r, r] = 1.0
        for j in range(ERRORS):
            a[r, j] += g[r][0] * jac[0, j] + g[r][1] * jac[1, j]
    a[0, ERROR.heading] -= s * sn
    a[1, ERROR.heading] += s * c
    for r in range(3):
        for j in range(ERRORS):
            total = 0.0
            for k in range(ERRORS):
                total += a[r, k] * cov[k, j]
            rows[r, j] = total
    for r in range(3):
        for q in range(3):
            total = 0.0
            for k in range(ERRORS):
                total += rows[r, k] * a[q, k]
            pose[r, q] = total + (g[r][0] * (noise[0, 0] * g[q][0] + noise[0, 1] * g[q][1]) + g[r][1] * (noise[1, 0] * g[q][0] + noise[1, 1] * g[q][1]))
    for r in range(3):
        for j in range(3, ERRORS):
            cov[r, j] = cov[j, r] = rows[r, j]
        for q in range(3):
            cov[r, q] = pose[r, q]


@numba.njit(cache=True, error_model="numpy")
def pose_covariance(cov: np.ndarray, heading: float, lag: np.ndarray, out: np.ndarray) -> None:
    """The reported pose covariance's six entries (COVARIANCE_FIELDS) into `out`: the propagated
    one plus the quantisation lag `lag` (2, 2) of the increment (s along the heading, alpha)."""
    c, sn = math.cos(heading), math.sin(heading)
    out[0] = cov[0, 0] + lag[0, 0] * c * c
    out[1] = cov[0, 1] + lag[0, 0] * c * sn
    out[2] = cov[0, 2] + lag[0, 1] * c
    out[3] = cov[1, 1] + lag[0, 0] * sn * sn
    out[4] = cov[1, 2] + lag[0, 1] * sn
    out[5] = cov[2, 2] + lag[1, 1]



@numba.njit(cache=True, error_model="numpy", **INNER)
def wheel_variances(p: np.void, s_left: float, s_right: float) -> tuple[float, float]:
    """The random variance (m²) of each wheel's arc over a step of these arcs (m): slip and
    spurious ticks both grow with the distance rolled (m² per metre each), whatever the step."""
    return (p.slip_var + p.tick_var_left) * abs(s_left), (p.slip_var + p.tick_var_right) * abs(s_right)


@numba.njit(cache=True, error_model="numpy", **INNER)
def mouse_variance(p: np.void, s: float, alpha: float) -> float:
    """The random variance (m²) of each mouse axis over a step of this increment: its noise
    (m² per metre) times the floor the sensor passed, (s - alpha m_y, alpha m_x)."""
    return p.mouse_var * math.hypot(s - alpha * p.mount_y, alpha * p.mount_x)


@numba.njit(cache=True, error_model="numpy")
def add_offset(point: np.ndarray, pose: np.ndarray, weight: float, out: np.ndarray) -> None:
    """Add `weight` times the outer product of `point`'s offset from `pose` (both (3,)) to the
    covariance entries `out` (COVARIANCE_FIELDS), its heading within a half turn as the NEES
    takes an error's (`sim.analysis.nees`): a point 245 degrees one way lies 115 the other."""
    dx, dy = point[0] - pose[0], point[1] - pose[1]
    dt = (point[2] - pose[2] + math.pi) % (2.0 * math.pi) - math.pi
    out[0] += weight * dx * dx
    out[1] += weight * dx * dy
    out[2] += weight * dx * dt
    out[3] += weight * dy * dy
    out[4] += weight * dy * dt
    out[5] += weight * dt * dt


@numba.njit(cache=True, error_model="numpy", **INNER)
def nodes_of(point: int) -> tuple[int, int, int]:
    """Which node (`bots.odometry.layout.NODES`) sigma point `point` takes for each of three
    calibration errors: the base-3 digits of point + 1 (point 0 is the first beside the estimate).
    (All three in one call: one taking the error's number compiled once for each constant it was
    called with, three compiles on a first run.)"""
    digits = point + 1
    return digits % 3, digits // 3 % 3, digits // 9 % 3


@numba.njit(cache=True, error_model="numpy")
def point_weight(point: int, count: int) -> float:
    """The weight of sigma point `point` of `count` (3**errors - 1): its nodes' weights' product."""
    weight, digits, size = 1.0, point + 1, count + 1
    while size > 1:
        weight *= NODE_WEIGHTS[digits % 3]
        digits, size = digits // 3, size // 3
    return weight


def _point_weights() -> np.ndarray:
    """`point_weight(point, count)` at [count, point] for every count of sigma points (3**errors -
    1) up to SIGMAS (the same products in the same order: the same bits), and at MOUSE_SIGMAS the
    mouse's seven-node weights, other rows 0."""
    table = np.zeros((SIGMAS + 1, SIGMAS))
    count = 2
    while count <= SIGMAS:
        table[count, :count] = [point_weight.py_func(i, count) for i in range(count)]
        count = 3 * count + 2
    assert not table[MOUSE_SIGMAS].any(), "the mouse's points' count is one of the three-node rules'"
    table[MOUSE_SIGMAS, :MOUSE_SIGMAS] = MOUSE_NODE_WEIGHTS
    return table


POINT_WEIGHTS = _point_weights()
"""Every sigma point's weight (`_point_weights`): looked up, not worked out for each point every step."""


@numba.njit(cache=True, error_model="numpy")
def add_spread(sigmas: np.ndarray, count: int, pose: np.ndarray, out: np.ndarray) -> None:
    """Add the spread of the first `count` sigma points about `pose` to the covariance entries
    `out` (COVARIANCE_FIELDS): the calibration's part of the error, by Gauss-Hermite cubature
    (each point weighs `point_weight`, the estimate itself the rest; `POINT_WEIGHTS`)."""
    for i in range(count):
        add_offset(sigmas[i], pose, POINT_WEIGHTS[count, i], out)


@numba.njit(cache=True, error_model="numpy", inline="always")
def carry_noise(entries: np.ndarray, turns: np.ndarray, share: float, noise: tuple[float, float, float]) -> None:
    """`propagate` of pose covariances without calibration errors, one a sigma point, in place:
    `entries` (COVARIANCE_FIELDS, points), each point's increment of length turns[0] with noise
    `noise` (its entries ss, s-alpha, alpha-alpha) laid along a direction of cosine turns[1], sine
    turns[2] (`turns` (3, points), as `lay_point` leaves them), at share * s from the turn. (Points
    along the last axis: one loop of plain arithmetic over them, which the compiler vectorises.)"""
    n_ss, n_sa, n_aa = noise
    for i in range(entries.shape[1]):
        s, c, sn = turns[0, i], turns[1, i], turns[2, i]
        xx, xy, xt, yy, yt, tt = entries[0, i], entries[1, i], entries[2, i], entries[3, i], entries[4, i], entries[5, i]
        ax, ay = -s * sn, s * c  # (d pose / d heading)
        xt_, yt_ = xt + ax * tt, yt + ay * tt
        lever = share * s
        gx, gy = -lever * sn, lever * c  # (d pose / d alpha; d pose / d s is (c, sn, 0))
        ux0, ux1 = n_ss * c + n_sa * gx, n_sa * c + n_aa * gx
        uy0, uy1 = n_ss * sn + n_sa * gy, n_sa * sn + n_aa * gy
        entries[0, i] = xx + ax * xt + ax * xt_ + (c * ux0 + gx * ux1)
        entries[1, i] = xy + ax * yt + ay * xt_ + (sn * ux0 + gy * ux1)
        entries[2, i] = xt_ + ux1
        entries[3, i] = yy + ay * yt + ay * yt_ + (sn * uy0 + gy * uy1)
        entries[4, i] = yt_ + uy1
        entries[5, i] = tt + n_aa


@numba.njit(cache=True, error_model="numpy", inline="always")
def lay_point(points: np.ndarray, turns: np.ndarray, i: int, s: float, chord: float, alpha: float, share: float) -> None:
    """Sigma point `i`'s step, in place: its pose (row `i` of `points`) laid by the arc's `chord`
    along heading + share * alpha (`MID_ANGLE`, `END_HEADING`; `sim.kinematics.batch.advance_chord`'s
    operations: the same bits), its arc length s and that direction's cosine and sine left in column `i` of
    `turns` for `carry_noise`."""
    x, y, heading = points[i, 0], points[i, 1], points[i, 2]
    direction = heading + share * alpha
    c, sn = math.cos(direction), math.sin(direction)
    turns[0, i], turns[1, i], turns[2, i] = s, c, sn
    points[i, 0], points[i, 1], points[i, 2] = x + chord * c, y + chord * sn, heading + alpha


@numba.njit(cache=True, error_model="numpy", inline="always")
def noise_of(noise: np.ndarray) -> tuple[float, float, float]:
    """An increment's noise (2, 2; `wheel_terms`) as `carry_noise` takes it: its three entries."""
    return noise[0, 0], noise[0, 1], noise[1, 1]


@numba.njit(cache=True, error_model="numpy")
def add_point_noise(points: np.ndarray, count: int, cov: np.ndarray, out: np.ndarray) -> None:
    """Replace in the covariance entries `out` the random part `cov` (ERRORS, ERRORS: the
    estimate's, carried along its own path) by its mean over the first `count` sigma points'
    paths: each point's entries `points` (COVARIANCE_FIELDS, count) weigh as its offset
    (`POINT_WEIGHTS`), the estimate's own the rest."""
    own = (cov[0, 0], cov[0, 1], cov[0, 2], cov[1, 1], cov[1, 2], cov[2, 2])
    for k in range(6):
        total = 0.0
        for i in range(count):
            total += POINT_WEIGHTS[count, i] * (points[k, i] - own[k])
        out[k] += total


@numba.njit(cache=True, error_model="numpy", inline="always")
def lay(pose: np.ndarray, s: float, alpha: float, end_heading: bool) -> None:
    """`ArcOdometry.update`: the pose after the arc, in place."""
    pose[0], pose[1], pose[2] = advance_one(pose[0], pose[1], pose[2], s, alpha, end_heading)
