"""Consistency of an estimate's covariance: the normalised estimation error squared (NEES).

For a pose error e (estimate minus truth, heading wrapped) and the covariance P the estimator
reported, NEES = e^T P^-1 e. An estimator whose errors are what its covariance says has NEES
chi-square distributed with 3 degrees of freedom: its mean over N independent runs, at the same
time, lies in the 95 % interval of chi2(3N) / N (Bar-Shalom, Li and Kirubarajan 2001, §5.4.2).
Below the interval the estimator is too cautious; above, over-confident.

A covariance with a direction of (almost) no uncertainty, its smallest eigenvalue below FLOOR, is
degenerate: the lateral error at the start, before anything moved, or an estimator that believes
only in quantisation (a belief of zero errors), whose lateral error is then "impossible" and its
NEES millions. There NEES has no meaning and is none (nan), not a huge number.

One run's NEES at one time is one draw of chi2(3) (95 % of them within 0.22-9.35, `interval(1)`);
its average over the samples of one run is not: successive samples are correlated, so no
chi-square interval applies to it. Consistency is judged by the mean over independent runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from bots.uncertainty import square
from sim.kinematics import wrap_angle

FLOOR = 1e-12
"""The smallest variance (m², rad²) a covariance may give a direction and still be used: (1 µm)²,
(1 µrad)², far below anything a sensor resolves (a mouse count's quantisation: (18 µm)²)."""
DOF = 3


def degenerate(entries: np.ndarray) -> np.ndarray:
    """(T,) whether each of (T, 6) covariance entries has a direction of variance below FLOOR."""
    return np.linalg.eigvalsh(square(entries)).min(axis=-1) < FLOOR


def nees(truth: np.ndarray, estimate: np.ndarray, entries: np.ndarray) -> np.ndarray:
    """(T,) NEES of (T, 3) poses against (T, 3) truth with (T, 6) covariance entries
    (`bots.uncertainty.COVARIANCE_FIELDS`); nan where the covariance is `degenerate`."""
    error = np.asarray(estimate, dtype=np.float64) - np.asarray(truth, dtype=np.float64)
    error[:, 2] = wrap_angle(error[:, 2])
    cov = square(entries)
    singular = degenerate(entries)
    cov[singular] = np.eye(3)  # (left out below)
    out = np.einsum("ti,ti->t", error, np.linalg.solve(cov, error[..., None])[..., 0])
    out[singular] = np.nan
    return out


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
    """The `level` two-sided interval of the mean NEES of `runs` independent consistent runs at
    one time (chi2(3 runs) / runs); `runs` = 1 is one run's NEES at one time."""
    tail = 0.5 * (1.0 - level)
    dof = DOF * runs
    return _chi2_quantile(tail, dof) / runs, _chi2_quantile(1.0 - tail, dof) / runs


@dataclass(frozen=True)
class OverRuns:
    """The mean NEES of independent runs at one time (each run's last sample) against its 95 %
    interval: mean, runs (those with a defined NEES), the interval and the verdict."""

    mean: float
    runs: int
    low: float
    high: float

    @property
    def verdict(self) -> str:
        """'consistent' inside the interval, 'over-confident' above it, 'too cautious' below; 'none'
        without runs."""
        if not self.runs:
            return "none"
        return "consistent" if self.low <= self.mean <= self.high else "over-confident" if self.mean > self.high else "too cautious"

    def __str__(self) -> str:
        if not self.runs:
            return "-"
        return f"{self.mean:.3g} in {self.low:.2f}-{self.high:.2f} ({self.verdict}, {self.runs} runs)"


def over_runs(values: np.ndarray) -> OverRuns:
    """`OverRuns` of each run's NEES at the same time; undefined ones (nan) left out."""
    values = np.asarray(values, dtype=np.float64)
    values = values[np.isfinite(values)]
    if not len(values):
        return OverRuns(math.nan, 0, math.nan, math.nan)
    low, high = interval(len(values))
    return OverRuns(float(values.mean()), len(values), low, high)
