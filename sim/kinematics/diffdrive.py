"""Differential drive: body twist <-> wheel speeds, instantaneous centre of curvature (seed 003).

Wheel speeds are rim speeds (m/s, signed, forward positive), v the axle-centre speed (m/s),
omega the yaw rate (rad/s, counter-clockwise positive), b the track width (m). All functions
broadcast over batch axes.
"""

from __future__ import annotations

import numpy as np


def wheel_speeds_from_twist(v: np.ndarray, omega: np.ndarray, track: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(v, omega) -> (v_left, v_right): omega (R -+ b/2) = v_l, v_r (seed 003, eq 1)."""
    v = np.asarray(v, dtype=np.float64)
    half = 0.5 * np.asarray(omega, dtype=np.float64) * track
    return v - half, v + half


def twist_from_wheel_speeds(v_left: np.ndarray, v_right: np.ndarray, track: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(v_left, v_right) -> (v, omega) with omega = (v_r - v_l)/b (seed 003, eq 2)."""
    v_left = np.asarray(v_left, dtype=np.float64)
    v_right = np.asarray(v_right, dtype=np.float64)
    return 0.5 * (v_left + v_right), (v_right - v_left) / track


def turn_radius(v_left: np.ndarray, v_right: np.ndarray, track: float | np.ndarray) -> np.ndarray:
    """Signed radius R = b (v_l + v_r) / (2 (v_r - v_l)) (m, seed 003 eq 2): positive when the
    centre lies to the left; +-inf on a straight line (v_l = v_r), 0 when spinning on the spot."""
    v_left = np.asarray(v_left, dtype=np.float64)
    v_right = np.asarray(v_right, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        radius = track * (v_left + v_right) / (2.0 * (v_right - v_left))
    # standing still has no defined centre; call it straight rather than NaN
    return np.where(np.isnan(radius), np.inf, radius)


def curvature(v_left: np.ndarray, v_right: np.ndarray, track: float | np.ndarray) -> np.ndarray:
    """Signed curvature 1/R (1/m): finite and continuous through straight motion, which is why
    controllers prefer it to R; +-inf when spinning on the spot, 0 when standing still."""
    v, omega = twist_from_wheel_speeds(v_left, v_right, track)
    with np.errstate(divide="ignore", invalid="ignore"):
        kappa = omega / v
    return np.where(np.isnan(kappa), 0.0, kappa)


def icc(pose: np.ndarray, v_left: np.ndarray, v_right: np.ndarray, track: float | np.ndarray) -> np.ndarray:
    """World position of the instantaneous centre of curvature, (x - R sin th, y + R cos th)
    (seed 003, eq 3); infinite components on a straight line, the axle centre on the spot."""
    pose = np.asarray(pose, dtype=np.float64)
    radius = turn_radius(v_left, v_right, track)
    with np.errstate(invalid="ignore"):
        offset_x = -radius * np.sin(pose[..., 2])
        offset_y = radius * np.cos(pose[..., 2])
    # on a straight line R*0 gives NaN for an axis the heading is aligned with: it is infinite
    offset_x = np.where(np.isnan(offset_x), np.inf, offset_x)
    offset_y = np.where(np.isnan(offset_y), np.inf, offset_y)
    return np.stack((pose[..., 0] + offset_x, pose[..., 1] + offset_y), axis=-1)
