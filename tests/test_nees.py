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
