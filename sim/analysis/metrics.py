"""Odometry against ground truth: the standard trajectory error metrics of one run.

Truth and estimate are (T, 3) poses (x, y m; heading rad, continuous) sampled at the same times.
Both start at the same pose (the run loop resets every estimator to the true start), so the
absolute trajectory error is taken without the usual rigid alignment (Sturm et al. 2012 align
because SLAM frames are arbitrary; here an alignment would hide the error at the start).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.analysis.nees import nees
from sim.kinematics import relative_increment, wrap_angle

BLOCK = 65536
"""Samples compared at a time: bounded temporaries for hour-long runs."""


def _steps(poses: np.ndarray, previous: np.ndarray | None = None) -> np.ndarray:
    """(T,) distance (m) of each pose from the one before; the first's from `previous` (1, 3), or
    0 without one."""
    before = poses[:1] if previous is None else previous
    return np.hypot(*np.diff(np.concatenate((before, poses))[:, :2], axis=0).T)


def path_lengths(poses: np.ndarray) -> np.ndarray:
    """(T,) distance driven from the first pose to each pose (m), summed over the samples."""
    return np.cumsum(_steps(np.asarray(poses)))


class _Pairs:
    """Relative pose errors as evo computes them (`evo_rpe ... --delta 1 --delta_unit m`, Grupp's
    evo, its defaults: consecutive pairs, chosen on the estimate's path; Sturm et al. 2012's
    definition): the first pose is marked, then, walking the estimate's positions, each pose where
    the path summed since the last mark reaches `delta` (as evo 1.38; evo 1.36 did not mark the
    first pose, so its first pair started a `delta` later), and each two consecutive marks i, j are a pair, whose error is E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) for truth Q
    and estimate P: its translation part |trans E| (m) and its rotation angle |rot E| (rad).
    Read block by block: only the last mark and the path since it are kept."""

    def __init__(self, delta: float):
        self.delta = delta
        self._path = 0.0  # summed since the last mark, in order, as evo sums it
        self._previous: np.ndarray | None = None  # the estimate's last position
        self._mark: tuple[np.ndarray, np.ndarray] | None = None  # (truth, estimate) at the last mark

    def add(self, truth: np.ndarray, estimate: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(translation errors (m), rotation errors (rad)) of the pairs that end in this block."""
        steps = _steps(estimate, self._previous)
        self._previous = estimate[-1:].copy()
        marks, start = ([], 0) if self._mark is not None else ([0], 1)
        while start < len(steps):
            path = np.cumsum(np.concatenate(([self._path], steps[start:])))[1:]  # (added in evo's order, from the last mark on)
            if path[-1] < self.delta:
                self._path = float(path[-1])
                break
            marks.append(start + int(np.searchsorted(path, self.delta, side="left")))  # (the path never falls: the first at or past delta)
            self._path, start = 0.0, marks[-1] + 1
        firsts = [self._mark] if self._mark is not None else []
        truths = np.array([m[0] for m in firsts] + [truth[i] for i in marks]).reshape(-1, 3)
        estimates = np.array([m[1] for m in firsts] + [estimate[i] for i in marks]).reshape(-1, 3)
        if marks:
            self._mark = (truth[marks[-1]].copy(), estimate[marks[-1]].copy())
        if len(truths) < 2:
            return np.empty(0), np.empty(0)
        error = relative_increment(relative_increment(truths[:-1], truths[1:]), relative_increment(estimates[:-1], estimates[1:]))
        return np.hypot(error[:, 0], error[:, 1]), np.abs(wrap_angle(error[:, 2]))


def relative_pose_errors(truth: np.ndarray, estimate: np.ndarray, delta: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(translation errors (m), rotation errors (rad)) of the relative motion between poses
    `delta` metres of the estimate's path apart, as `evo_rpe` (see `_Pairs`)."""
    truth, estimate = np.asarray(truth, dtype=np.float64), np.asarray(estimate, dtype=np.float64)
    if not len(truth):
        return np.empty(0), np.empty(0)
    return _Pairs(delta).add(truth, estimate)


@dataclass(frozen=True)
class Metrics:
    """How far an estimate strayed from the truth over one run (m, rad, s).

    final_position_error, final_heading_error (wrapped, estimate minus truth): at the last sample.
    max_position_error: worst distance at any sample.
    ate_rmse: absolute trajectory error, RMS of the position distances over all samples.
    path_length: metres the robot really drove; duration: seconds covered.
    final_error_per_metre: final_position_error / path_length (nan for no motion).
    rpe_translation, rpe_rotation: relative pose error as `evo_rpe -d 1 -u m` computes it (pairs
        of poses 1 m of the estimate's path apart, `_Pairs`): the RMS of the pairs' translation
        parts (m) and of their rotation angles (rad); nan with fewer than two marks (under 2 m).
    heading_drift_per_metre, heading_drift_per_minute: |final heading error| over the path length
        (rad/m) and over the duration (rad/min).
    nees_mean, nees_final: the normalised estimation error squared (`sim.analysis.nees`) averaged
        over the samples where it is defined and at the last one (nan for an estimate without a
        covariance, or where it is degenerate); a consistent estimator's nees_final averages 3
        over runs (`sim.analysis.nees.interval`); nees_mean, an average over one run's correlated
        samples, has no such interval.
    nees_defined: the share of samples whose covariance is not degenerate (nan without one).
    """

    final_position_error: float
    final_heading_error: float
    max_position_error: float
    ate_rmse: float
    path_length: float
    duration: float
    final_error_per_metre: float
    rpe_translation: float
    rpe_rotation: float
    heading_drift_per_metre: float
    heading_drift_per_minute: float
    nees_mean: float = math.nan
    nees_final: float = math.nan
    nees_defined: float = math.nan


def _ratio(value: float, scale: float) -> float:
    return value / scale if scale > 0 else math.nan


class Comparison:
    """An estimate against the truth, fed block by block in time order (`add`), so that an
    hour-long run is compared without holding it all at once; `metrics()` at any point."""

    def __init__(self, segment: float = 1.0):
        self.segment = segment
        self._pairs = _Pairs(segment)
        self._first_time = self._last_time = math.nan
        self._last_truth = self._last_estimate = None
        self._driven = 0.0
        self._count = 0
        self._sum_squares = self._max = 0.0
        self._rpe_squares, self._rpe_angle_squares, self._rpe_count = 0.0, 0.0, 0
        self._nees_sum, self._nees_last, self._nees_count, self._covariances = 0.0, math.nan, 0, 0

    def add(self, times: np.ndarray, truth: np.ndarray, estimate: np.ndarray, covariance: np.ndarray | None = None) -> None:
        """The next samples: (n,) times and (n, 3) poses of both, and the estimate's (n, 6)
        covariance entries where it has them."""
        if truth.shape != estimate.shape or truth.ndim != 2 or truth.shape[1] != 3 or len(times) != len(truth):
            raise ValueError(f"expected truth and estimate of the same shape (T, 3) and T times, got {truth.shape}, {estimate.shape}, {times.shape}")
        if not len(truth):
            return
        driven = np.cumsum(np.concatenate(([self._driven], _steps(truth, self._last_truth))))[1:]  # as one cumsum over the run, however split
        with np.errstate(over="ignore", invalid="ignore"):  # an estimate that ran off scores inf (or nan), without a warning
            distance = np.hypot(*(estimate[:, :2] - truth[:, :2]).T)
            rpe, rpe_angle = self._pairs.add(truth, estimate)
            self._sum_squares += float(np.sum(distance**2))
            self._rpe_squares += float(np.sum(rpe**2))
            self._rpe_angle_squares += float(np.sum(rpe_angle**2))
        if self._count == 0:
            self._first_time = float(times[0])
        self._count += len(truth)
        self._max = max(self._max, float(distance.max()))
        self._rpe_count += len(rpe)
        self._driven, self._last_time = float(driven[-1]), float(times[-1])
        self._last_truth, self._last_estimate = truth[-1:].copy(), estimate[-1:].copy()
        if covariance is not None:
            normalised = nees(truth, estimate, covariance)
            defined = np.isfinite(normalised)
            self._nees_sum += float(np.sum(normalised[defined]))
            self._nees_count += int(np.count_nonzero(defined))
            self._covariances += len(normalised)
            self._nees_last = float(normalised[-1])

    def metrics(self) -> Metrics:
        """The metrics of everything added so far."""
        if not self._count:
            raise ValueError("no samples to compare")
        final = float(np.hypot(*(self._last_estimate[0, :2] - self._last_truth[0, :2])))
        heading = float(wrap_angle(self._last_estimate[0, 2] - self._last_truth[0, 2]))
        length, duration = self._driven, self._last_time - self._first_time
        return Metrics(
            final_position_error=final,
            final_heading_error=heading,
            max_position_error=self._max,
            ate_rmse=math.sqrt(self._sum_squares / self._count),
            path_length=length,
            duration=duration,
            final_error_per_metre=_ratio(final, length),
            rpe_translation=math.sqrt(self._rpe_squares / self._rpe_count) if self._rpe_count else math.nan,
            rpe_rotation=math.sqrt(self._rpe_angle_squares / self._rpe_count) if self._rpe_count else math.nan,
            heading_drift_per_metre=_ratio(abs(heading), length),
            heading_drift_per_minute=_ratio(abs(heading), duration / 60.0),
            nees_mean=self._nees_sum / self._nees_count if self._nees_count else math.nan,
            nees_final=self._nees_last,
            nees_defined=self._nees_count / self._covariances if self._covariances else math.nan,
        )


def compare(times: np.ndarray, truth: np.ndarray, estimate: np.ndarray, segment: float = 1.0) -> Metrics:
    """Metrics of `estimate` against `truth`, both (T, 3) at `times` (T,)."""
    times, truth, estimate = np.asarray(times, dtype=np.float64), np.asarray(truth), np.asarray(estimate)
    comparison = Comparison(segment)
    for start in range(0, len(truth), BLOCK):
        rows = slice(start, start + BLOCK)
        comparison.add(times[rows], truth[rows], estimate[rows])
    return comparison.metrics()


def compare_run(result) -> dict[str, dict[str, Metrics]]:  # noqa: ANN001 (sim.run.samples.RunResult; run imports bots)
    """Robot name -> estimator name -> Metrics for every estimate a run recorded, read through
    block by block (`RunResult.blocks`: memory does not grow with the run's length)."""
    comparisons = {log.name: {name: Comparison() for name in log.estimate_names} for log in result.robots}
    for rows in result.blocks():
        times = result.time_array(rows)
        for log in result.robots:
            truth = log.truth_array(rows)
            covariances = log.covariance_arrays(rows)
            for name, poses in log.estimate_arrays(rows).items():
                comparisons[log.name][name].add(times, truth, poses, covariances.get(name))
    return {robot: {name: c.metrics() for name, c in by_name.items()} for robot, by_name in comparisons.items()}


def path_length(result, log) -> float:  # noqa: ANN001 (sim.run.samples.RunResult and one of its RobotLogs)
    """Metres a robot of a run really drove, read through block by block."""
    total, last = 0.0, None
    for rows in result.blocks():
        truth = log.truth_array(rows)
        total += float(np.sum(_steps(truth, last)))
        last = truth[-1:].copy()
    return total
