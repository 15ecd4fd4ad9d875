"""Differential drive (seed 003): twist <-> wheel speeds, turn radius and ICC, and the rigid-body
fact behind them: every point of the body moves perpendicular to its ray from the ICC."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from strategies import TRACK, floats, pose, track_width

from sim.kinematics import (
    apply_increment,
    arc_increment,
    curvature,
    icc,
    turn_radius,
    twist_from_wheel_speeds,
    wheel_speeds_from_twist,
)

speed = floats(-1.0, 1.0)


@given(speed, floats(-20.0, 20.0), track_width)
@settings(max_examples=200)
def test_twist_wheel_speed_round_trip(v: float, omega: float, track: float) -> None:
    v_left, v_right = wheel_speeds_from_twist(v, omega, track)
    v_back, omega_back = twist_from_wheel_speeds(v_left, v_right, track)
    assert v_back == pytest.approx(v, abs=1e-15 * (1 + abs(omega) * track))
    assert omega_back == pytest.approx(omega, abs=1e-14 * (1 + abs(v) / track))
    # seed 003 eq 2 written out
    assert v_back == pytest.approx((v_left + v_right) / 2, abs=1e-16)
    assert omega_back == pytest.approx((v_right - v_left) / track, rel=1e-15, abs=1e-300)


@given(speed, speed, track_width)
@settings(max_examples=200)
def test_wheel_to_twist_round_trip(v_left: float, v_right: float, track: float) -> None:
    back = wheel_speeds_from_twist(*twist_from_wheel_speeds(v_left, v_right, track), track)
    np.testing.assert_allclose(back, (v_left, v_right), rtol=0, atol=1e-15)


@given(speed, speed, track_width)
@settings(max_examples=200)
def test_turn_radius_is_seed_003_and_satisfies_its_wheel_equations(v_left: float, v_right: float, track: float) -> None:
    assume(abs(v_right - v_left) > 1e-6)
    radius = float(turn_radius(v_left, v_right, track))
    assert radius == pytest.approx(track * (v_left + v_right) / (2 * (v_right - v_left)), rel=1e-15)
    _, omega = twist_from_wheel_speeds(v_left, v_right, track)
    # seed 003 eq 1: both wheels turn with the same omega about the ICC
    assert omega * (radius + track / 2) == pytest.approx(v_right, abs=1e-12)
    assert omega * (radius - track / 2) == pytest.approx(v_left, abs=1e-12)
    # curvature 1/R, signed like omega: +-inf on the spot
    kappa = 1 / radius if radius else math.copysign(math.inf, float(omega))
    assert float(curvature(v_left, v_right, track)) == pytest.approx(kappa, rel=1e-12)


@pytest.mark.parametrize("speed_", (0.2, -0.2))
@pytest.mark.parametrize("heading", (0.0, 0.3, math.pi / 2, -2.0))
def test_straight_line_has_an_infinite_radius_and_no_finite_icc(speed_: float, heading: float) -> None:
    assert np.isinf(turn_radius(speed_, speed_, TRACK))
    assert float(curvature(speed_, speed_, TRACK)) == 0.0
    centre = icc(np.array([1.0, 2.0, heading]), speed_, speed_, TRACK)
    assert not np.isnan(centre).any()
    assert not np.isfinite(centre).any()


def test_standing_still_counts_as_straight() -> None:
    assert np.isinf(turn_radius(0.0, 0.0, TRACK))
    assert float(curvature(0.0, 0.0, TRACK)) == 0.0


@given(pose, floats(0.01, 1.0))
def test_spot_turn_has_zero_radius_and_the_axle_centre_as_icc(start: np.ndarray, v: float) -> None:
    assert float(turn_radius(-v, v, TRACK)) == 0.0
    assert np.isinf(curvature(-v, v, TRACK))
    np.testing.assert_array_equal(icc(start, -v, v, TRACK), start[:2])


@given(pose, speed, speed, track_width)
@settings(max_examples=200)
def test_icc_is_seed_003_eq_3(start: np.ndarray, v_left: float, v_right: float, track: float) -> None:
    assume(abs(v_right - v_left) > 1e-6)
    radius = track * (v_left + v_right) / (2 * (v_right - v_left))
    expected = (start[0] - radius * math.sin(start[2]), start[1] + radius * math.cos(start[2]))
    np.testing.assert_allclose(icc(start, v_left, v_right, track), expected, rtol=1e-13, atol=1e-13)
    # the ICC lies on the axle line, |R| from the axle centre, to the left for R > 0
    offset = icc(start, v_left, v_right, track) - start[:2]
    forward = np.array([math.cos(start[2]), math.sin(start[2])])
    assert offset @ forward == pytest.approx(0.0, abs=1e-12 * (1 + abs(radius)))
    assert forward[0] * offset[1] - forward[1] * offset[0] == pytest.approx(radius, rel=1e-12, abs=1e-12)


@given(pose, speed, speed, track_width, st.tuples(floats(-0.2, 0.2), floats(-0.2, 0.2)))
@settings(max_examples=200)
def test_every_body_point_moves_perpendicular_to_its_ray_from_the_icc(
    start: np.ndarray, v_left: float, v_right: float, track: float, body_point: tuple[float, float]
) -> None:
    """Rigid motion: the world velocity of a body point p is v*forward + omega x (p - axle centre);
    it is perpendicular to p - ICC and has length |omega| * |p - ICC|. The wheels are such points."""
    assume(abs(v_right - v_left) > 1e-6)
    v, omega = (float(q) for q in twist_from_wheel_speeds(v_left, v_right, track))
    c, s = math.cos(start[2]), math.sin(start[2])
    for bx, by in (body_point, (0.0, track / 2), (0.0, -track / 2)):
        p = start[:2] + np.array([c * bx - s * by, s * bx + c * by])
        r = p - start[:2]
        velocity = v * np.array([c, s]) + omega * np.array([-r[1], r[0]])
        ray = p - icc(start, v_left, v_right, track)
        scale = np.linalg.norm(velocity) * np.linalg.norm(ray)
        assert abs(velocity @ ray) <= 1e-12 * max(scale, 1.0)
        assert np.linalg.norm(velocity) == pytest.approx(abs(omega) * np.linalg.norm(ray), rel=1e-9, abs=1e-12)
    # the wheels' rim speeds come back out
    left_wheel_speed = v - omega * track / 2
    assert left_wheel_speed == pytest.approx(v_left, abs=1e-14)


@given(pose, speed, speed, floats(0.001, 0.5))
@settings(max_examples=200)
def test_an_exact_step_rotates_every_body_point_about_the_icc(start: np.ndarray, v_left: float, v_right: float, dt: float) -> None:
    """Seed 003 eq 4 for the whole body: after one exact arc step, each body point is its old
    position rotated by omega*dt about the ICC."""
    assume(abs(v_right - v_left) > 1e-3)
    v, omega = (float(q) for q in twist_from_wheel_speeds(v_left, v_right, TRACK))
    end = apply_increment(start, arc_increment(v * dt, omega * dt))
    centre = icc(start, v_left, v_right, TRACK)
    turn = omega * dt
    rotation = np.array([[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]])
    for body_point in ((0.0, 0.0), (0.05, 0.02), (-0.015, 0.0)):
        before = apply_increment(start, np.array([*body_point, 0.0]))[:2]
        after = apply_increment(end, np.array([*body_point, 0.0]))[:2]
        expected = centre + rotation @ (before - centre)
        scale = 1 + np.abs(centre).max()
        np.testing.assert_allclose(after, expected, rtol=0, atol=1e-12 * scale)
