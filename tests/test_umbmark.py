"""UMBmark: the first-order formulas, and a c't-Bot with a wheel diameter mismatch and a track
error set in the world, calibrated by its own squares."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bots.ctbot import CTBOT
from bots.odometry.base import Geometry
from sim.analysis.umbmark import (
    OdometrySquare,
    calibrate,
    corrected_geometry,
    return_error,
    square_world,
    systematic_errors,
    umbmark,
)

DIAMETER_ERROR = (-0.005, 0.005)  # right wheel 1.005 % larger than the left, mean diameter right
TRACK_ERROR = 0.02
TRUE_RATIO = (1 + DIAMETER_ERROR[1]) / (1 + DIAMETER_ERROR[0])


def test_formulas_invert_the_first_order_model():
    """Centres of gravity from the model in the module docstring give back alpha and beta."""
    side, alpha, beta = 1.0, 0.03, -0.05
    cg_ccw = np.array([2 * side * (beta - alpha), -2 * side * (beta - alpha)])
    cg_cw = np.array([-2 * side * (beta + alpha), -2 * side * (beta + alpha)])
    a, b, e_d, e_b = systematic_errors(cg_cw, cg_ccw, side, 0.1)
    assert (a, b) == pytest.approx((alpha, beta))
    radius = (side / 2) / math.sin(beta / 2)
    assert e_d == pytest.approx((radius + 0.05) / (radius - 0.05)) and e_d < 1  # curving right: right wheel smaller
    assert e_b == pytest.approx(90 / (90 - math.degrees(alpha)))


def test_correction_sets_the_ratio_and_keeps_the_mean_diameter():
    corrected = corrected_geometry(Geometry((0.05, 0.05), 0.1), 1.02, 1.03)
    left, right = corrected.wheel_diameters
    assert right / left == pytest.approx(1.02)
    assert (left + right) / 2 == pytest.approx(0.05)
    assert corrected.track_width == pytest.approx(0.103)


def test_square_driven_by_odometry_closes_on_an_error_free_robot():
    error = return_error(CTBOT, True, 1.0, Geometry.nominal(CTBOT), square_world(), (0.5, 1.5, 0.0), seed=0)
    assert np.hypot(*error) < 0.01


def test_umbmark_recovers_diameter_and_track_errors_and_the_correction_shrinks_the_error():
    """The c't-Bot's 97 mm track turns a 1 % diameter mismatch into 5 deg of curving per 1 m leg,
    beyond the first-order model: the first round finds 0.88 % and 0.7 % (seen). A second round,
    starting from the first round's geometry, sees small errors and lands within 10 % of both
    (seen: 0.996 % and 1.97 %; return error 0.39 m -> 8 mm)."""
    robot = CTBOT.with_changes(encoders={"diameter_error": DIAMETER_ERROR, "track_error": TRACK_ERROR, "slip_std": 0.00008})
    first, second = calibrate(robot, rounds=2, runs=3)
    assert first.e_d > 1 and first.e_b > 1  # the signs are right from the start
    left, right = second.corrected.wheel_diameters
    # within 10 % of both errors after the second round (the docstring's bar; seen 0.9 % and 1.5 % off)
    assert right / left - 1 == pytest.approx(TRUE_RATIO - 1, rel=0.1)
    assert second.corrected.track_width / robot.track_width - 1 == pytest.approx(TRACK_ERROR, rel=0.1)
    after = umbmark(robot, runs=3, geometry=second.corrected, seed=100)
    assert first.max_error / after.max_error >= 5
    assert np.all(np.hypot(*np.concatenate((after.errors_cw, after.errors_ccw)).T) < first.max_error / 5)


def test_square_driver_refuses_nonsense():
    with pytest.raises(ValueError, match="side_m"):
        OdometrySquare(side_m=0.0)
