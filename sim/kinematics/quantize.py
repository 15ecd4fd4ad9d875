"""Quantisation with the remainder carried: whole counts now, the fraction in the next step.

Encoders and the mouse sensor both count whole events; c't-Sim floors and keeps the fractional
rest, so the sum of counts over any number of steps equals floor(total + initial carry): no drift.
"""

from __future__ import annotations

import numpy as np


def _floor_and_fraction(total: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(floor(total), total - floor(total)) with the fraction kept in [0, 1): for a total just
    below an integer (e.g. -1e-20) the difference rounds to 1.0; count that whole event instead."""
    whole = np.floor(total)
    fraction = total - whole
    full = fraction >= 1.0
    return whole + full, np.where(full, 0.0, fraction)[()]


def quantize(value: np.ndarray, carry: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(counts, new carry) for `value` (in counts, real) plus the `carry` from the previous step.

    counts = floor(value + carry) as int64; new carry in [0, 1)."""
    total = np.asarray(value, dtype=np.float64) + carry
    counts, fraction = _floor_and_fraction(total)
    return counts.astype(np.int64), fraction


def quantize_series(values: np.ndarray, carry: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Counts for T consecutive steps at once (`values` of shape (T, ...)), and the final carry.

    Differences of floor(running total): the same counts as T calls of `quantize`, up to the
    rounding of the running sum."""
    running = np.cumsum(values, axis=0) + carry
    floors, fractions = _floor_and_fraction(running)
    counts = np.diff(floors, axis=0, prepend=np.zeros_like(floors[:1]))
    return counts.astype(np.int64), fractions[-1]
