"""Trajectory metrics on synthetic trajectories with closed-form values."""

from __future__ import annotations

import math
import os
import shutil
import subprocess

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bots.commands import Twist
from bots.controller import FunctionController
from bots.ctbot import CTBOT
from sim.analysis.export import read_tum, write_tum
from sim.analysis.metrics import (
    BLOCK,
    Comparison,
    compare,
    compare_run,
    path_lengths,
    relative_pose_errors,
)
from sim.kinematics import wrap_angle
from sim.run.loop import RobotSetup, run
from sim.world.files import load_world

# 10 m straight along x at 1 m/s, sampled every 0.125 s (exact in binary, so 1 m stretches are exact)
TIMES = np.arange(81) * 0.125
STRAIGHT = np.column_stack((TIMES * 1.0, np.zeros_like(TIMES), np.zeros_like(TIMES)))


def test_a_perfect_estimate_has_zero_error():
    m = compare(TIMES, STRAIGHT, STRAIGHT)
    assert (m.final_position_error, m.ate_rmse, m.rpe_translation, m.rpe_rotation, m.heading_drift_per_metre) == (0, 0, 0, 0, 0)
    assert m.path_length == 10.0 and m.duration == 10.0


def test_scale_error():
    """Estimate x' = (1 + k) x: error k*x at every sample; RPE pairs 1 m of the estimate's path
    apart (8 samples of 0.1275 m: 1.02 m) span 1 m of truth: k on every pair, no rotation."""
    k = 0.02
    estimate = STRAIGHT * [1 + k, 1, 1]
    m = compare(TIMES, STRAIGHT, estimate)
    assert m.final_position_error == pytest.approx(10 * k)
    assert m.max_position_error == pytest.approx(10 * k)
    assert m.ate_rmse == pytest.approx(k * math.sqrt(np.mean(STRAIGHT[:, 0] ** 2)))
    assert m.final_error_per_metre == pytest.approx(k)
    assert m.rpe_translation == pytest.approx(k) and m.rpe_rotation == 0.0
    assert m.final_heading_error == 0.0


def test_ate_rmse_is_the_root_mean_square_of_the_position_distances():
    """ATE RMSE = sqrt(mean |p_est - p_true|^2) over every sample, in the plane, heading errors not
    counted: random offsets in x and y, and one 3 m error among 81 samples (3/sqrt(81) = 1/3)."""
    rng = np.random.default_rng(5)
    offsets = rng.normal(scale=0.01, size=(len(TIMES), 2))
    estimate = STRAIGHT + np.column_stack((offsets, rng.normal(size=len(TIMES))))
    m = compare(TIMES, STRAIGHT, estimate)
    # the same sum in another order: a few ulps apart
    assert m.ate_rmse == pytest.approx(math.sqrt(np.mean(np.sum(offsets**2, axis=1))), rel=1e-12)
    one_off = STRAIGHT.copy()
    one_off[-1, 1] += 3.0
    assert compare(TIMES, STRAIGHT, one_off).ate_rmse == pytest.approx(1 / 3, rel=1e-15)
    assert compare(TIMES, STRAIGHT, one_off).max_position_error == 3.0


def test_heading_error_duration_and_segment_on_a_run_that_starts_late_and_turned():
    """A run starting at t = 100 s with heading 1 rad: the heading error is the estimate's minus the
    truth's (0.2 rad), the duration the time between first and last sample (10 s), and the RPE of
    pairs 2 m apart 2k."""
    k = 0.02
    truth = STRAIGHT + [0.0, 0.0, 1.0]
    estimate = truth * [1 + k, 1, 1] + [0.0, 0.0, 0.2]
    m = compare(TIMES + 100.0, truth, estimate)
    assert m.final_heading_error == pytest.approx(0.2)
    assert m.duration == 10.0
    assert compare(TIMES + 100.0, truth, truth * [1 + k, 1, 1], segment=2.0).rpe_translation == pytest.approx(2 * k)


def test_a_run_longer_than_one_block_is_compared_whole():
    """More samples than `compare` reads at once (BLOCK): every sample counts, the last is the last."""
    n = BLOCK + 4463
    times = np.arange(n) * 0.001
    truth = np.column_stack((times, np.zeros(n), np.zeros(n)))
    estimate = truth * [1.01, 1, 1]
    m = compare(times, truth, estimate)
    assert m.final_position_error == pytest.approx(0.01 * times[-1])
    assert m.ate_rmse == pytest.approx(0.01 * math.sqrt(np.mean(times**2)), rel=1e-12)  # summed in another order
    assert m.duration == pytest.approx(times[-1])


def test_heading_drift_and_a_path_turned_about_the_start():
    """Estimate turned by phi about the start: final error 2 L sin(phi/2), heading error phi; a
    heading drifting at c rad/s drifts c*60 per minute and c*T/L per metre."""
    phi = 0.1
    c, s = math.cos(phi), math.sin(phi)
    turned = np.column_stack((STRAIGHT[:, 0] * c, STRAIGHT[:, 0] * s, np.full_like(TIMES, phi)))
    m = compare(TIMES, STRAIGHT, turned)
    assert m.final_position_error == pytest.approx(2 * 10 * math.sin(phi / 2))
    assert m.final_heading_error == pytest.approx(phi)
    assert m.heading_drift_per_minute == pytest.approx(phi / 10 * 60)
    assert m.heading_drift_per_metre == pytest.approx(phi / 10)
    # every 1 m stretch of the turned path is a 1 m stretch of the true one: no relative error
    assert m.rpe_translation == pytest.approx(0.0, abs=1e-12) and m.rpe_rotation == pytest.approx(0.0, abs=1e-12)


def test_final_heading_error_is_wrapped():
    estimate = STRAIGHT + [0, 0, 1.5 * math.pi]
    assert compare(TIMES, STRAIGHT, estimate).final_heading_error == pytest.approx(-0.5 * math.pi)
    assert wrap_angle(2 * math.pi + 0.25) == pytest.approx(0.25)


def test_rpe_on_a_circle_with_a_heading_rate_error():
    """Truth: circle of radius r. Estimate: the same speed, radius r' = r/(1 + e). Every pair 1 m
    apart starts at a pose where both move along x, so the relative error is the distance between
    the end points of 1 m arcs of radius r and r' from the origin, and the angle between their
    ends, 1/r' - 1/r = e/r, the same for every pair."""
    r, e = 2.0, 0.05
    d = np.linspace(0, 6.0, 601)
    truth = np.column_stack((r * np.sin(d / r), r * (1 - np.cos(d / r)), d / r))
    r2 = r / (1 + e)
    estimate = np.column_stack((r2 * np.sin(d / r2), r2 * (1 - np.cos(d / r2)), d / r2))
    errors, angles = relative_pose_errors(truth, estimate, 1.0)
    assert path_lengths(truth)[-1] == pytest.approx(2 * r * 600 * math.sin(0.01 / (2 * r)), rel=1e-12)
    point_true = np.array([r * math.sin(1 / r), r * (1 - math.cos(1 / r))])
    point_est = np.array([r2 * math.sin(1 / r2), r2 * (1 - math.cos(1 / r2))])
    assert np.allclose(errors, np.hypot(*(point_est - point_true)), rtol=2e-2)  # chords sum to just under 1 m: pairs span 101 samples
    assert np.ptp(errors) < 0.02 * errors.max()
    assert np.allclose(angles, e / r, rtol=2e-2)


def test_shape_mismatch_is_refused():
    with pytest.raises(ValueError, match="same shape"):
        compare(TIMES, STRAIGHT, STRAIGHT[:-1])


def test_compare_run_gives_metrics_per_robot_and_estimator():
    result = run(load_world("empty"), [RobotSetup(CTBOT, FunctionController(lambda t, r: Twist(0.1, 0.3)))], 2.0)
    metrics = compare_run(result)
    assert list(metrics) == [CTBOT.name]
    assert set(metrics[CTBOT.name]) == {"encoders", "firmware", "mouse", "fused"}
    encoders = metrics[CTBOT.name]["encoders"]
    assert encoders.path_length == pytest.approx(0.2, rel=1e-6)
    assert math.isnan(encoders.rpe_translation)  # shorter than one pair 1 m apart
    assert encoders.final_position_error < 0.01


def _wander(seed: int, n: int) -> tuple[np.ndarray, np.ndarray]:
    """A random walk of n poses (steps up to 2 cm, stops included) and an estimate that drifts from it."""
    rng = np.random.default_rng(seed)
    step = rng.uniform(0, 0.02, n) * (rng.random(n) < 0.8)
    heading = np.cumsum(rng.normal(0, 0.05, n))
    truth = np.column_stack((np.cumsum(step * np.cos(heading)), np.cumsum(step * np.sin(heading)), heading))
    return truth, truth + np.cumsum(rng.normal(0, 1e-4, (n, 3)), axis=0)


@settings(max_examples=40)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(2, 600), cuts=st.lists(st.integers(1, 599), max_size=6))
def test_a_comparison_read_in_blocks_equals_one_read_at_once(seed, n, cuts):
    """Block boundaries change nothing but the order of the ATE sum: the stretches of the RPE and
    the path length are the same additions in the same order (bit for bit); sums of squares
    regrouped differ by round-off, 1e-12 relative for a few hundred positive terms."""
    truth, estimate = _wander(seed, n)
    times = np.arange(n) * 0.01
    whole = compare(times, truth, estimate)
    comparison = Comparison()
    edges = [0, *sorted({c for c in cuts if c < n}), n]
    for a, b in zip(edges[:-1], edges[1:]):
        comparison.add(times[a:b], truth[a:b], estimate[a:b])
    split = comparison.metrics()
    assert (split.path_length, split.final_position_error, split.max_position_error, split.duration) == (
        whole.path_length, whole.final_position_error, whole.max_position_error, whole.duration)
    assert split.ate_rmse == pytest.approx(whole.ate_rmse, rel=1e-12)
    assert (split.rpe_translation, split.rpe_rotation) == pytest.approx((whole.rpe_translation, whole.rpe_rotation), rel=1e-12, nan_ok=True)


def test_standing_still_adds_no_stretches():
    """RPE pairs are marked by metres of path, not samples: a robot that waits (here 5000
    samples) has the pairs of one that does not."""
    moving = np.column_stack((np.linspace(0, 3, 301), np.zeros(301), np.zeros(301)))
    waiting = np.concatenate((moving[:150], np.repeat(moving[150:151], 5000, axis=0), moving[151:]))
    count = len(relative_pose_errors(moving, moving, 1.0)[0])
    assert len(relative_pose_errors(waiting, waiting, 1.0)[0]) == count
    assert count in (2, 3)  # marks at 0, 1, 2 m; whether 100 steps of 1 cm reach 3 m again is round-off


def test_a_run_reads_back_the_same_in_any_blocks_across_its_streamed_windows(monkeypatch):
    """A run's logs go to a file a window of rows at a time (`sim.run.samples.WINDOW`) and are
    read back mapped from it: whole, in blocks that do not line up with the windows, and written
    through windows of 97 rows or of the whole run, the values are the same, bit for bit; and what
    is read back cannot be written to (the recorded rows are the run's)."""
    from sim.run import samples

    def wander(window: int):
        monkeypatch.setattr(samples, "WINDOW", window)
        return run(load_world("empty"), [RobotSetup(CTBOT, FunctionController(lambda t, r: Twist(0.1, 0.3)))], 30.0)

    result, whole = wander(97), wander(10**6)
    log, reference = result.robots[0], whole.robots[0]
    blocks = list(result.blocks(size=777))
    assert [b.start for b in blocks] == list(range(0, len(result), 777)) and blocks[-1].stop == len(result) == 3001
    np.testing.assert_array_equal(np.concatenate([log.truth_array(rows) for rows in blocks]), reference.truth_array())
    np.testing.assert_array_equal(result.time, whole.time)
    for name, poses in reference.estimate_arrays().items():
        np.testing.assert_array_equal(np.concatenate([log.estimate_arrays(rows)[name] for rows in blocks]), poses)
    for name, entries in reference.covariance_arrays().items():
        np.testing.assert_array_equal(log.covariance_arrays()[name], entries)
    for name, values in reference.readings(slice(0, 3001)).items():
        np.testing.assert_array_equal(np.concatenate([log.readings(rows)[name] for rows in blocks]), values)
    assert not log.truth_array().flags.writeable and not log.truth_array(slice(5, 9)).flags.writeable


def test_rpe_is_what_evo_rpe_prints(tmp_path):
    """The same TUM files through `evo_rpe tum TRUTH EST -d 1 -u m` (translation part) and with
    `-r angle_rad`: the RMSE evo prints equals ours to half its last digit (6 decimals)."""
    evo = shutil.which("evo_rpe")
    if evo is None:
        pytest.skip("evo is not installed (pip install -e '.[evo]' brings evo_rpe)")
    truth, estimate = _wander(49, 3000)
    estimate[:, 2] += np.linspace(0.0, 0.3, len(estimate))  # a heading drift for the rotation part
    times = np.arange(len(truth)) * 0.01
    write_tum(tmp_path / "truth.tum", times, truth)
    write_tum(tmp_path / "estimate.tum", times, estimate)
    _, truth = read_tum(tmp_path / "truth.tum")  # (as written: the files' digits)
    _, estimate = read_tum(tmp_path / "estimate.tum")
    ours = compare(times, truth, estimate)
    for relation, value in (("trans_part", ours.rpe_translation), ("angle_rad", ours.rpe_rotation)):
        printed = subprocess.run([evo, "tum", str(tmp_path / "truth.tum"), str(tmp_path / "estimate.tum"), "-d", "1", "-u", "m", "-r", relation],
                                 capture_output=True, text=True, check=True, env={**os.environ, "MPLBACKEND": "Agg"}).stdout  # fmt: skip
        rmse = float(next(line.split()[1] for line in printed.splitlines() if line.split()[:1] == ["rmse"]))
        assert value == pytest.approx(rmse, rel=0, abs=5.000001e-7), (relation, printed)
