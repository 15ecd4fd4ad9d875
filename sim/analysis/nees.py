"""Consistency of an estimate's covariance: the normalised estimation error squared (NEES).

For a pose error e (estimate minus truth, heading wrapped) and the covariance P the estimator
reported, NEES = e^T P^-1 e. An estimator whose errors are what its covariance says has NEES
chi-square distributed with 3 degrees of freedom: its mean over N independent runs, at the same
time, lies in the 95 % interval of chi2(3N) / N (Bar-Shalom, Li and Kirubarajan 2001, §5.4.2).
Below the interval the estimator is too cautious; above, over-confident.

A covariance with a direction of no uncertainty (the lateral error at the start, before anything
moved) is singular: FLOOR is added to its diagonal, far below anything a sensor resolves.
"""

from __future__ import annotations

import math

import numpy as np

from bots.uncertainty import square
from sim.kinematics import wrap_angle

FLOOR = 1e-12
"""Added to a covariance's diagonal (m², rad²): (1 µm)², (1 µrad)²."""
DOF = 3


def nees(truth: np.ndarray, estimate: np.ndarray, entries: np.ndarray) -> np.ndarray:
    """(T,) NEES of (T, 3) poses against (T, 3) truth with (T, 6) covariance entries
    (`bots.uncertainty.COVARIANCE_FIELDS`)."""
    error = np.asarray(estimate, dtype=np.float64) - np.asarray(truth, dtype=np.float64)
    error[:, 2] = wrap_angle(error[:, 2])
    cov = square(entries) + FLOOR * np.eye(3)
    return np.einsum("ti,ti->t", error, np.linalg.solve(cov, error[..., None])[..., 0])


def _chi2_cdf(x: float, dof: int) -> float:
    """P(chi2(dof) <= x): the regularised lower incomplete gamma P(dof/2, x/2) by its power
    series (Abramowitz and Stegun 6.5.29), which converges for every x."""
    a, half = 0.5 * dof, 0.5 * x
    if half <= 0.0:
        return 0.0
    term = total = 1.0 / a
    n = 0
    while term > 1e-17 * total:
        n += 1
        term *= half / (a + n)
        total += term
    return math.exp(a * math.log(half) - half - math.lgamma(a)) * total


def _chi2_quantile(p: float, dof: int) -> float:
    """The p-quantile of chi2(dof), by bisection of `_chi2_cdf`."""
    low, high = 0.0, dof + 20.0 * math.sqrt(2.0 * dof) + 20.0
    for _ in range(200):
        middle = 0.5 * (low + high)
        low, high = (middle, high) if _chi2_cdf(middle, dof) < p else (low, middle)
    return 0.5 * (low + high)


def interval(runs: int, level: float = 0.95) -> tuple[float, float]:
    """The `level` two-sided interval of the mean NEES of `runs` independent consistent runs
    (chi2(3 runs) / runs)."""
    tail = 0.5 * (1.0 - level)
    dof = DOF * runs
    return _chi2_quantile(tail, dof) / runs, _chi2_quantile(1.0 - tail, dof) / runs
