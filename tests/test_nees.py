"""NEES and its interval (`sim.analysis.nees`) against closed forms."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sim.analysis.nees import degenerate, interval, nees


def test_nees_is_the_error_squared_in_the_covariance_s_units():
    truth = np.zeros((2, 3))
    estimate = np.array([[0.02, 0.0, 0.0], [0.0, 0.01, 0.1]])
    entries = np.array([[1e-4, 0, 0, 1e-4, 0, 1e-2]] * 2)  # sigma 1 cm, 1 cm, 0.1 rad
    np.testing.assert_allclose(nees(truth, estimate, entries), [4.0, 2.0])


def test_a_degenerate_covariance_has_no_nees():
    """Quantisation only: no lateral uncertainty; a lateral error would read as millions."""
    entries = np.array([[1e-6, 0, 0, 0, 0, 1e-4], [1e-6, 0, 0, 1e-6, 0, 1e-4]])
    assert degenerate(entries).tolist() == [True, False]
    values = nees(np.zeros((2, 3)), np.full((2, 3), 0.001), entries)
    assert math.isnan(values[0]) and values[1] == pytest.approx(2.0 + 1e-2)


def test_the_interval_is_chi_square_over_runs():
    """chi2(3) 2.5 % and 97.5 % quantiles 0.2158 and 9.3484 (tables); for 40 runs chi2(120)/40:
    91.573/40 and 152.211/40 (the 2.29-3.81 of the maze table)."""
    assert interval(1) == pytest.approx((0.21580, 9.34840), abs=1e-4)
    assert interval(40) == pytest.approx((91.573 / 40, 152.211 / 40), abs=1e-4)


def test_the_run_table_keeps_its_columns_apart_and_says_what_its_nees_is():
    """Numbers of any size stay apart (once '0.501288956.3'); a degenerate NEES is '-' and the note
    says what one run's NEES can tell."""
    from sim.cli.output import table

    estimates = {"huge": {"final_position_error": 0.5012889, "ate_rmse": 123456.789, "final_heading_error": 1.0, "nees_final": 80e6},
                 "none": {"final_position_error": 0.1, "ate_rmse": 0.1, "final_heading_error": 0.0, "nees_final": math.nan}}  # fmt: skip
    summary = {"world": {"name": "w"}, "seed": 0, "noise": "none", "time": 1.0, "reason": "duration",
               "robots": [{"name": "bot", "distance": 1.0, "collisions": 0, "fell": False, "goal_time": None, "estimates": estimates}]}  # fmt: skip
    lines = table(summary).splitlines()
    header, huge, none = lines[1], lines[3], lines[4]
    assert huge.split() == ["huge", "0.5013", "123456.7890", "57.30", "8e+07"]
    assert none.split()[-1] == "-" and "0.22-9.35" in lines[-1]
    assert all(len(line) <= len(header) for line in (huge, none))  # right-aligned under their headers


def test_a_kept_run_replays_to_the_estimates_it_logged(tmp_path):
    """`consistency` keeps each seed's readings; replayed through the default estimators they give
    the run's own estimates and covariances bit for bit (so changed estimators can be scored on
    the same runs), and the NEES it takes at 10 / 50 / 100 % is the log's at those samples."""
    from sim.experiments.consistency import Scenario, Track, consistency, nees_at, replay, sample_rows

    short = Scenario(duration=3.0)
    table = consistency([5], short, keep=tmp_path)
    track = Track.load(tmp_path / "seed5.npz")
    again = replay(track, short)
    for name, poses in track.estimates.items():
        assert np.array_equal(again.estimates[name], poses) and np.array_equal(again.covariances[name], track.covariances[name]), name
    rows = sample_rows(len(track.time))
    assert rows == [math.ceil(0.1 * (len(track.time) - 1)), math.ceil(0.5 * (len(track.time) - 1)), len(track.time) - 1]
    for name, values in nees_at(track).items():
        np.testing.assert_array_equal(table.per_seed[name][0], values)
        np.testing.assert_array_equal(values, nees(track.truth[rows], track.estimates[name][rows], track.covariances[name][rows]))


def test_tails_tell_a_heavy_tail_from_runs_that_are_all_off():
    """`Consistency.tails`: one run's NEES against chi-square(3), its median and the shares of
    runs outside one run's interval (0.22-9.35), so a mean over seeds that strays because of a
    few runs reads differently from one where every run is off."""
    from sim.experiments.consistency import Consistency

    heavy = np.full(40, 1.5)
    heavy[:2] = [100.0, 0.1]  # (the mean 3.94: outside 2.29-3.81, by one run)
    table = Consistency(list(range(40)), (1.0,), {"heavy": heavy[:, None], "off": np.full((40, 1), 6.0)}).tails().splitlines()
    assert table[2] == "| heavy | 1.50 (2.5% / 2.5%) |" and table[3] == "| off | 6.00 (0.0% / 0.0%) |"
    assert "(chi-square: 2.37)" in table[-1] and "below 0.22 and above 9.35" in table[-1]


def test_where_a_covariance_does_not_hold_the_run_says_so():
    """summary.json and the run's table say, for each shipped estimate, where its covariance is
    known not to tell the truth (`ArcOdometry.caveat`, docs/odometry.md); a user's estimate has none."""
    from bots.odometry.defaults import caveats
    from sim.cli.output import table
    from sim.experiments import simulate

    summary = simulate("maze", duration=0.2).summary()
    said = summary["robots"][0]["caveats"]
    assert set(said) == {"encoders", "firmware", "mouse", "fused"} and said == caveats()
    printed = table(summary).splitlines()
    for name, caveat in said.items():
        assert f"  {name}: {caveat}" in printed
