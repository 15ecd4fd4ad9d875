"""Wheel encoders: wheel rotation -> signed ticks with the remainder carried, and back.

The c't-Bot counts 60 edges per wheel revolution (30 black and 30 white stripes), 2.97 mm of rim.
"""

from __future__ import annotations

import math

import numpy as np

from sim.kinematics.quantize import quantize, quantize_series

CTBOT_TICKS_PER_REV = 60


def ticks_per_metre(wheel_radius: float | np.ndarray, ticks_per_rev: int = CTBOT_TICKS_PER_REV) -> float | np.ndarray:
    """Ticks per metre of rim travel."""
    return ticks_per_rev / (2 * math.pi * np.asarray(wheel_radius))


def ticks_from_arcs(
    s_wheel: np.ndarray, carry: np.ndarray, wheel_radius: float | np.ndarray, ticks_per_rev: int = CTBOT_TICKS_PER_REV
) -> tuple[np.ndarray, np.ndarray]:
    """Signed ticks for wheel arc lengths `s_wheel` (m) in one step, and the carry to pass to the
    next step (fraction of a tick, in [0, 1))."""
    return quantize(np.asarray(s_wheel, dtype=np.float64) * ticks_per_metre(wheel_radius, ticks_per_rev), carry)


def ticks_from_arc_series(
    s_wheel: np.ndarray, carry: np.ndarray, wheel_radius: float | np.ndarray, ticks_per_rev: int = CTBOT_TICKS_PER_REV
) -> tuple[np.ndarray, np.ndarray]:
    """`ticks_from_arcs` for T steps at once (`s_wheel` of shape (T, ...))."""
    return quantize_series(np.asarray(s_wheel, dtype=np.float64) * ticks_per_metre(wheel_radius, ticks_per_rev), carry)


def arcs_from_ticks(ticks: np.ndarray, wheel_radius: float | np.ndarray, ticks_per_rev: int = CTBOT_TICKS_PER_REV) -> np.ndarray:
    """Wheel arc lengths (m) that `ticks` stand for."""
    return np.asarray(ticks, dtype=np.float64) / ticks_per_metre(wheel_radius, ticks_per_rev)
