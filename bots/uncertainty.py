"""How sure an odometry estimate is: its error covariance, propagated step by step from the
sensors' noise model, in compiled kernels shared by the Python estimators and the batch.

The error state of every estimator has ERRORS entries: the pose error (x, y m; heading rad) and
four relative calibration errors the robot's own code cannot see (left and right wheel scale,
track width, mouse resolution), each constant through a run. A step's increment (arc length s,
heading change alpha) is wrong by `jac @ errors + n`, n ~ `noise` (2, 2); laying it down moves the
pose error by the increment's Jacobians (the mid-angle chord of seed 002 eq 1.12, or the
firmware's end heading), as in Chong and Kleeman 1997 ("Accurate odometry and error modelling for
a mobile robot", their per-wheel distance variance growing with the distance rolled, plus the
systematic errors of UMBmark as constant states, which make the pose covariance of a wrong track
width grow with the rotation and that of a wheel mismatch with distance squared).

Quantisation is not a random walk here: counts are carried, so each channel lags the truth by
less than one count at any time (uniform, variance count²/12) and that lag never adds up. It is
added to the reported pose covariance (`pose_covariance`), never to the propagated one.

The believed noise (`Belief.of`) is the robot description's own noise figures, read as its data
sheet: the random spreads as they are, the systematic errors by their size only (a standard
deviation), never their sign or which wheel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from bots.spec import RobotSpec

ERRORS = 7
"""Entries of an estimator's error state."""
X, Y, HEADING, LEFT_SCALE, RIGHT_SCALE, TRACK_SCALE, MOUSE_SCALE = range(ERRORS)
COVARIANCE_FIELDS = ("cov_xx", "cov_xy", "cov_xt", "cov_yy", "cov_yt", "cov_tt")
"""The six distinct entries of a pose covariance (m², m·rad, rad²), in the order `pose_covariance` writes."""


@dataclass(frozen=True)
class Belief:
    """The noise an estimator assumes (per step where rates; relative where scales).

    slip_var: variance of a wheel's relative slip per step; tick_rate: probability per step of a
    spurious +-1 tick on a wheel; wheel_scale_std, track_std, mouse_scale_std: standard deviation
    of the unknown relative errors of each wheel's diameter, the track width and the mouse's
    resolution; mouse_var: variance of a mouse count per step and axis (counts²)."""

    slip_var: float = 0.0
    tick_rate: float = 0.0
    wheel_scale_std: float = 0.0
    track_std: float = 0.0
    mouse_var: float = 0.0
    mouse_scale_std: float = 0.0

    @classmethod
    def of(cls, robot: RobotSpec) -> Belief:
        """The robot description's noise as its data sheet: each wheel's diameter error as the RMS
        of the two (the mismatch's size, not which wheel), the others by their magnitude."""
        enc, mouse = robot.encoders, robot.mouse
        left, right = enc.diameter_error
        return cls(
            slip_var=enc.slip_std**2,
            tick_rate=enc.tick_noise,
            wheel_scale_std=math.sqrt(0.5 * (left * left + right * right)),
            track_std=abs(enc.track_error),
            mouse_var=0.0 if mouse is None else mouse.noise_std**2,
            mouse_scale_std=0.0 if mouse is None else abs(mouse.scale_error),
        )

    def prior(self) -> np.ndarray:
        """(ERRORS, ERRORS) the error covariance at the start: the pose known, the scales not."""
        cov = np.zeros((ERRORS, ERRORS))
        cov[LEFT_SCALE, LEFT_SCALE] = cov[RIGHT_SCALE, RIGHT_SCALE] = self.wheel_scale_std**2
        cov[TRACK_SCALE, TRACK_SCALE] = self.track_std**2
        cov[MOUSE_SCALE, MOUSE_SCALE] = self.mouse_scale_std**2
        return cov


@numba.njit(cache=True)
def wheel_terms(s_left: float, s_right: float, alpha: float, track: float, var_left: float, var_right: float,
                jac: np.ndarray, noise: np.ndarray) -> None:  # fmt: skip
    """The encoder increment's error model, in place: `jac` (2, ERRORS) of (s, alpha) on the
    scales for wheel arcs s_left, s_right (m) and heading change alpha over `track` (m); `noise`
    (2, 2) for independent wheel-arc variances var_left, var_right (m²)."""
    jac[:, :] = 0.0
    jac[0, LEFT_SCALE], jac[0, RIGHT_SCALE] = 0.5 * s_left, 0.5 * s_right
    jac[1, LEFT_SCALE], jac[1, RIGHT_SCALE], jac[1, TRACK_SCALE] = -s_left / track, s_right / track, -alpha
    noise[0, 0] = 0.25 * (var_left + var_right)
    noise[0, 1] = noise[1, 0] = 0.5 * (var_right - var_left) / track
    noise[1, 1] = (var_left + var_right) / (track * track)


@numba.njit(cache=True)
def mouse_terms(s: float, alpha: float, mount_x: float, mount_y: float, var: float, jac: np.ndarray, noise: np.ndarray) -> None:
    """The mouse increment's error model, in place: `jac` on the resolution's error for the
    increment (s m, alpha rad), `noise` for a variance `var` (m²) of each axis's reading, through
    alpha = lateral/m_x, s = forward + alpha*m_y."""
    jac[:, :] = 0.0
    jac[0, MOUSE_SCALE], jac[1, MOUSE_SCALE] = -s, -alpha
    lever = mount_y / mount_x
    noise[0, 0] = var * (1.0 + lever * lever)
    noise[0, 1] = noise[1, 0] = var * lever / mount_x
    noise[1, 1] = var / (mount_x * mount_x)


@numba.njit(cache=True)
def propagate(cov: np.ndarray, heading: float, s: float, alpha: float, end_heading: bool, jac: np.ndarray, noise: np.ndarray) -> None:
    """`cov` (ERRORS, ERRORS) after laying the increment (s, alpha) from `heading` (rad, before
    the step) whose error is jac @ errors + n, n ~ noise: cov <- A cov A^T + G noise G^T, with A
    the identity but for the pose rows (d pose'/d pose and G @ jac, G = d pose'/d (s, alpha))."""
    angle = heading + (alpha if end_heading else 0.5 * alpha)
    c, sn = math.cos(angle), math.sin(angle)
    lever = s if end_heading else 0.5 * s
    g = ((c, -lever * sn), (sn, lever * c), (0.0, 1.0))
    a = np.zeros((3, ERRORS))
    for r in range(3):
        a[r, r] = 1.0
        for j in range(ERRORS):
            a[r, j] += g[r][0] * jac[0, j] + g[r][1] * jac[1, j]
    a[0, HEADING] -= s * sn
    a[1, HEADING] += s * c
    rows = np.zeros((3, ERRORS))  # a @ cov
    for r in range(3):
        for j in range(ERRORS):
            total = 0.0
            for k in range(ERRORS):
                total += a[r, k] * cov[k, j]
            rows[r, j] = total
    pose = np.zeros((3, 3))  # a @ cov @ a^T, + G noise G^T
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


@numba.njit(cache=True)
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


def square(entries: np.ndarray) -> np.ndarray:
    """(..., 3, 3) covariance matrices from their (..., 6) COVARIANCE_FIELDS entries."""
    xx, xy, xt, yy, yt, tt = np.moveaxis(np.asarray(entries, dtype=np.float64), -1, 0)
    return np.stack([np.stack([xx, xy, xt], -1), np.stack([xy, yy, yt], -1), np.stack([xt, yt, tt], -1)], -2)
