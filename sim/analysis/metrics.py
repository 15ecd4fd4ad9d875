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

RPE_SPACING = 0.01
"""Metres of true path between the starts of two RPE stretches."""
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


class _Stretches:
    """Relative pose errors (RPE, Sturm et al. 2012, over distance rather than time as in KITTI)
    of stretches of `segment` metres of true path, read block by block: a stretch starts at the
    first sample at or past every RPE_SPACING metres of path (so standing still adds no stretches)
    and ends at the first sample `segment` metres further on; its error is
    |trans((Q_i^-1 Q_j)^-1 (P_i^-1 P_j))| for truth Q and estimate P. Only stretches not yet ended
    are kept: at most segment / RPE_SPACING + 1."""

    def __init__(self, segment: float):
        self.segment = segment
        self._marks = 0  # starts placed so far: the next lies at _marks * RPE_SPACING m
        self._driven = np.empty(0)
        self._truth = np.empty((0, 3))
        self._estimate = np.empty((0, 3))

    def add(self, driven: np.ndarray, truth: np.ndarray, estimate: np.ndarray) -> np.ndarray:
        """Errors (m) of the stretches that end within this block of samples; `driven` (n,) is the
        true path length at each sample, continuing from the previous block."""
        marks = np.arange(self._marks, int(driven[-1] // RPE_SPACING) + 2) * RPE_SPACING
        marks = marks[marks <= driven[-1]]
        self._marks += len(marks)
        starts = np.unique(np.searchsorted(driven, marks))
        self._driven = np.concatenate((self._driven, driven[starts]))
        self._truth = np.concatenate((self._truth, truth[starts]))
        self._estimate = np.concatenate((self._estimate, estimate[starts]))
        ends = np.searchsorted(driven, self._driven + self.segment)
        done = int(np.count_nonzero(ends < len(driven)))  # a prefix: the starts are in path order
        j = ends[:done]
        true_motion = relative_increment(self._truth[:done], truth[j])
        estimated_motion = relative_increment(self._estimate[:done], estimate[j])
        self._driven, self._truth, self._estimate = self._driven[done:], self._truth[done:], self._estimate[done:]
        return np.hypot(*relative_increment(true_motion, estimated_motion)[:, :2].T)


def relative_pose_errors(truth: np.ndarray, estimate: np.ndarray, segment: float = 1.0) -> np.ndarray:
    """Translation errors (m) of the relative motion over stretches of `segment` metres of true
    path, one starting every RPE_SPACING metres (see `_Stretches`)."""
    truth, estimate = np.asarray(truth), np.asarray(estimate)
    if not len(truth):
        return np.empty(0)
    return _Stretches(segment).add(path_lengths(truth), truth, estimate)


@dataclass(frozen=True)
class Metrics:
    """How far an estimate strayed from the truth over one run (m, rad, s).

    final_position_error, final_heading_error (wrapped, estimate minus truth): at the last sample.
    max_position_error: worst distance at any sample.
    ate_rmse: absolute trajectory error, RMS of the position distances over all samples.
    path_length: metres the robot really drove; duration: seconds covered.
    final_error_per_metre: final_position_error / path_length (nan for no motion).
    rpe_per_metre: RMS relative position error over 1 m stretches of true path, one starting
        every RPE_SPACING of path, per metre (nan when the path is shorter than 1 m).
    heading_drift_per_metre, heading_drift_per_minute: |final heading error| over the path length
        (rad/m) and over the duration (rad/min).
    nees_mean, nees_final: the normalised estimation error squared (`sim.analysis.nees`) averaged
        over all samples and at the last one (nan for an estimate without a covariance); a
        consistent estimator's is 3 on average over runs.
    """

    final_position_error: float
    final_heading_error: float
    max_position_error: float
    ate_rmse: float
    path_length: float
    duration: float
    final_error_per_metre: float
    rpe_per_metre: float
    heading_drift_per_metre: float
    heading_drift_per_minute: float
    nees_mean: float = math.nan
    nees_final: float = math.nan


def _ratio(value: float, scale: float) -> float:
    return value / scale if scale > 0 else math.nan


class Comparison:
    """An estimate against the truth, fed block by block in time order (`add`), so that an
    hour-long run is compared without holding it all at once; `metrics()` at any point."""

    def __init__(self, segment: float = 1.0):
        self.segment = segment
        self._stretches = _Stretches(segment)
        self._first_time = self._last_time = math.nan
        self._last_truth = self._last_estimate = None
        self._driven = 0.0
        self._count = 0
        self._sum_squares = self._max = 0.0
        self._rpe_squares, self._rpe_count = 0.0, 0
        self._nees_sum, self._nees_last = 0.0, math.nan

    def add(self, times: np.ndarray, truth: np.ndarray, estimate: np.ndarray, covariance: np.ndarray | None = None) -> None:
        """The next samples: (n,) times and (n, 3) poses of both, and the estimate's (n, 6)
        covariance entries where it has them."""
        if truth.shape != estimate.shape or truth.ndim != 2 or truth.shape[1] != 3 or len(times) != len(truth):
            raise ValueError(f"expected truth and estimate of the same shape (T, 3) and T times, got {truth.shape}, {estimate.shape}, {times.shape}")
        if not len(truth):
            return
        driven = np.cumsum(np.concatenate(([self._driven], _steps(truth, self._last_truth))))[1:]  # as one cumsum over the run, however split
        distance = np.hypot(*(estimate[:, :2] - truth[:, :2]).T)
        rpe = self._stretches.add(driven, truth, estimate)
        if self._count == 0:
            self._first_time = float(times[0])
        self._count += len(truth)
        self._sum_squares += float(np.sum(distance**2))
        self._max = max(self._max, float(distance.max()))
        self._rpe_squares += float(np.sum(rpe**2))
        self._rpe_count += len(rpe)
        self._driven, self._last_time = float(driven[-1]), float(times[-1])
        self._last_truth, self._last_estimate = truth[-1:].copy(), estimate[-1:].copy()
        if covariance is not None:
            normalised = nees(truth, estimate, covariance)
            self._nees_sum += float(np.sum(normalised))
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
            rpe_per_metre=math.sqrt(self._rpe_squares / self._rpe_count) / self.segment if self._rpe_count else math.nan,
            heading_drift_per_metre=_ratio(abs(heading), length),
            heading_drift_per_minute=_ratio(abs(heading), duration / 60.0),
            nees_mean=self._nees_sum / self._count if math.isfinite(self._nees_last) else math.nan,
            nees_final=self._nees_last,
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
    comparisons = {log.name: {name: Comparison() for name in log.estimate_arrays()} for log in result.robots}
    for rows in result.blocks():
        times = result.time[rows]
        for log in result.robots:
            truth = log.truth_array()[rows]
            covariances = log.covariance_arrays()
            for name, poses in log.estimate_arrays().items():
                covariance = covariances[name][rows] if name in covariances else None
                comparisons[log.name][name].add(times, truth, poses[rows], covariance)
    return {robot: {name: c.metrics() for name, c in by_name.items()} for robot, by_name in comparisons.items()}


def path_length(result, log) -> float:  # noqa: ANN001 (sim.run.samples.RunResult and one of its RobotLogs)
    """Metres a robot of a run really drove, read through block by block."""
    total, last = 0.0, None
    for rows in result.blocks():
        truth = log.truth_array()[rows]
        total += float(np.sum(_steps(truth, last)))
        last = truth[-1:].copy()
    return total
