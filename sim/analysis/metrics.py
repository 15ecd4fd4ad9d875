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

from sim.kinematics import relative_increment, wrap_angle

RPE_BLOCK = 65536
"""Segments per block in `relative_pose_errors`."""


def path_lengths(poses: np.ndarray) -> np.ndarray:
    """(T,) distance driven from the first pose to each pose (m), summed over the samples."""
    steps = np.hypot(*np.diff(np.asarray(poses)[:, :2], axis=0).T)
    return np.concatenate(([0.0], np.cumsum(steps)))


def relative_pose_errors(truth: np.ndarray, estimate: np.ndarray, segment: float = 1.0) -> np.ndarray:
    """Translation errors (m) of the relative motion over every stretch of `segment` metres of
    true path (RPE, Sturm et al. 2012, with distance instead of time windows, as KITTI):
    |trans((Q_i^-1 Q_j)^-1 (P_i^-1 P_j))| for each start i and the first j with d_j - d_i >= segment."""
    truth, estimate = np.asarray(truth), np.asarray(estimate)
    driven = path_lengths(truth)
    ends = np.searchsorted(driven, driven + segment)
    starts = np.nonzero(ends < len(driven))[0]
    ends = ends[starts]
    errors = np.empty(len(starts))
    for block in range(0, len(starts), RPE_BLOCK):  # bounded temporaries for hour-long runs
        i, j = starts[block : block + RPE_BLOCK], ends[block : block + RPE_BLOCK]
        true_motion = relative_increment(truth[i], truth[j])
        estimated_motion = relative_increment(estimate[i], estimate[j])
        errors[block : block + RPE_BLOCK] = np.hypot(*relative_increment(true_motion, estimated_motion)[:, :2].T)
    return errors


@dataclass(frozen=True)
class Metrics:
    """How far an estimate strayed from the truth over one run (m, rad, s).

    final_position_error, final_heading_error (wrapped, estimate minus truth): at the last sample.
    max_position_error: worst distance at any sample.
    ate_rmse: absolute trajectory error, RMS of the position distances over all samples.
    path_length: metres the robot really drove; duration: seconds covered.
    final_error_per_metre: final_position_error / path_length (nan for no motion).
    rpe_per_metre: RMS relative position error over 1 m stretches of true path, per metre
        (nan when the path is shorter than 1 m).
    heading_drift_per_metre, heading_drift_per_minute: |final heading error| over the path length
        (rad/m) and over the duration (rad/min).
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


def _ratio(value: float, scale: float) -> float:
    return value / scale if scale > 0 else math.nan


def compare(times: np.ndarray, truth: np.ndarray, estimate: np.ndarray, segment: float = 1.0) -> Metrics:
    """Metrics of `estimate` against `truth`, both (T, 3) at `times` (T,)."""
    times, truth, estimate = np.asarray(times, dtype=np.float64), np.asarray(truth), np.asarray(estimate)
    if truth.shape != estimate.shape or truth.ndim != 2 or truth.shape[1] != 3 or len(times) != len(truth) or not len(truth):
        raise ValueError(f"expected truth and estimate of the same shape (T, 3) and T times, got {truth.shape}, {estimate.shape}, {times.shape}")
    distance = np.hypot(*(estimate[:, :2] - truth[:, :2]).T)
    heading = float(wrap_angle(estimate[-1, 2] - truth[-1, 2]))
    length = float(path_lengths(truth)[-1])
    duration = float(times[-1] - times[0])
    rpe = relative_pose_errors(truth, estimate, segment)
    return Metrics(
        final_position_error=float(distance[-1]),
        final_heading_error=heading,
        max_position_error=float(distance.max()),
        ate_rmse=float(np.sqrt(np.mean(distance**2))),
        path_length=length,
        duration=duration,
        final_error_per_metre=_ratio(float(distance[-1]), length),
        rpe_per_metre=float(np.sqrt(np.mean(rpe**2))) / segment if len(rpe) else math.nan,
        heading_drift_per_metre=_ratio(abs(heading), length),
        heading_drift_per_minute=_ratio(abs(heading), duration / 60.0),
    )


def compare_run(result) -> dict[str, dict[str, Metrics]]:  # noqa: ANN001 (sim.run.RunResult; run imports bots)
    """Robot name -> estimator name -> Metrics for every estimate a run recorded."""
    times = result.time
    return {
        log.name: {name: compare(times, log.truth_array(), poses) for name, poses in log.estimate_arrays().items()}
        for log in result.robots
    }
