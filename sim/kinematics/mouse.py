"""The optical mouse sensor: exact ground displacement under its mount point, counts, and the
motion estimated back from counts (seed 002 §2, generalised to any mount point; DESIGN.md §4).

A sensor at (m_x, m_y) in the body frame, carried along an arc (centre arc length s, heading
change alpha), sees the ground move by (s - alpha*m_y, alpha*m_x) along its (forward, left) axes:
the seed's X = alpha*|MP|, Y = alpha*r for a sensor on the centre line, without c't-Sim's chord
approximation. Displacements are (..., 2) arrays (forward, left), in metres or counts.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.kinematics.arc import arc_increment, se2_log
from sim.kinematics.quantize import quantize, quantize_series

METRES_PER_INCH = 0.0254


def counts_per_metre(dpi: float | np.ndarray) -> float | np.ndarray:
    """Mouse counts per metre of ground motion at `dpi` counts per inch."""
    return np.asarray(dpi, dtype=np.float64) / METRES_PER_INCH


def mouse_displacement(s: np.ndarray, alpha: np.ndarray, mount: np.ndarray) -> np.ndarray:
    """Ground displacement (m) under a sensor at `mount` (..., 2) over an arc (s m, alpha rad)."""
    s = np.asarray(s, dtype=np.float64)
    alpha = np.asarray(alpha, dtype=np.float64)
    mount = np.asarray(mount, dtype=np.float64)
    return np.stack(np.broadcast_arrays(s - alpha * mount[..., 1], alpha * mount[..., 0]), axis=-1)


def mouse_displacement_from_increment(increment: np.ndarray, mount: np.ndarray) -> np.ndarray:
    """Ground displacement (m) under the sensor for any body increment (dx, dy, dtheta), read
    as the constant twist that produces it: the body's true motion when contacts bent its path."""
    twist = se2_log(increment)
    mount = np.asarray(mount, dtype=np.float64)
    return np.stack(
        (twist[..., 0] - twist[..., 2] * mount[..., 1], twist[..., 1] + twist[..., 2] * mount[..., 0]), axis=-1
    )


def mouse_counts(displacement: np.ndarray, carry: np.ndarray, dpi: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Counts for one step's displacement (m) and the carry for the next step (in [0, 1))."""
    return quantize(np.asarray(displacement, dtype=np.float64) * counts_per_metre(dpi)[..., None], carry)


def mouse_count_series(displacement: np.ndarray, carry: np.ndarray, dpi: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """`mouse_counts` for T steps at once (`displacement` of shape (T, ..., 2))."""
    return quantize_series(np.asarray(displacement, dtype=np.float64) * counts_per_metre(dpi)[..., None], carry)


class UnobservableRotation(ValueError):
    """A mouse on the wheel axle line (m_x = 0) sees no lateral motion from turning."""


@dataclass(frozen=True)
class MouseEstimator:
    """Motion from mouse counts (seed 002 §2.1): alpha = lateral/m_x, s = forward + alpha*m_y.

    mount: sensor position in the body frame (m); dpi: the resolution the robot believes.
    Built once per robot; refuses a mount point that cannot observe rotation."""

    mount: tuple[float, float]
    dpi: float = 400.0
    min_lever: float = 1e-4

    def __post_init__(self) -> None:
        m_x = float(self.mount[0])
        if not np.isfinite(m_x) or abs(m_x) < self.min_lever:
            raise UnobservableRotation(
                f"mouse mount point {tuple(self.mount)} lies on the wheel axle line (m_x = {m_x:g} m): "
                "a turn on the spot moves the ground under it along the sensor's forward axis only, "
                f"so rotation cannot be told from driving; mount it at least {self.min_lever:g} m "
                "in front of or behind the axle"
            )
        if not (np.isfinite(self.dpi) and self.dpi > 0):
            raise ValueError(f"mouse resolution must be a positive number of dpi, got {self.dpi!r}")

    def arc(self, counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(centre arc length s in m, heading change alpha in rad) from counts (..., 2)."""
        metres = np.asarray(counts, dtype=np.float64) / counts_per_metre(self.dpi)
        alpha = metres[..., 1] / self.mount[0]
        return metres[..., 0] + alpha * self.mount[1], alpha

    def increment(self, counts: np.ndarray) -> np.ndarray:
        """Body-frame pose increment (dx, dy, dtheta) from one step's counts (..., 2)."""
        return arc_increment(*self.arc(counts))
