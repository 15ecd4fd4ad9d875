"""The exact arc (seed 002; DESIGN.md §4): closed-form circles, continuity through straight motion,
SE(2) identities, and the firmware's end-heading variant against the geometry it gets wrong."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from strategies import (
    EPS,
    TRACK,
    alpha,
    analytic_pose,
    angle,
    arc_length,
    finite,
    pose,
    rotate_about,
    sinc,
    wheel_arc,
)

from sim.kinematics import (
    advance,
    advance_floats,
    apply_increment,
    arc_increment,
    compose,
    firmware_increment,
    half_angle_terms,
    integrate_arcs,
    relative_increment,
    relative_pose,
    se2_exp,
    se2_log,
    twist_from_wheel_speeds,
    wheel_arcs_to_arc,
    wheel_increment,
    wrap_angle,
)

START = np.array([0.3, -0.2, 0.7])
DTS = (0.001, 0.005, 0.01, 0.05, 0.1, 0.25, 0.5)
# (v_left, v_right) m/s: curves both ways, reversing, spin on the spot, straight, full c't-Bot speed
WHEEL_SPEEDS = ((0.1, 0.3), (0.3, -0.1), (-0.2, -0.1), (-0.3, 0.1), (0.2, -0.2), (0.2, 0.2), (-0.15, -0.15), (0.4483, 0.4))


def _constant_arcs(v_left: float, v_right: float, dt: float, duration: float = 10.0) -> tuple[np.ndarray, np.ndarray]:
    steps = round(duration / dt)
    return wheel_arcs_to_arc(np.full(steps, v_left * dt), np.full(steps, v_right * dt), TRACK)


# --- 10 s of a circle against its closed form ---------------------------------------------------


@pytest.mark.parametrize("dt", DTS)
@pytest.mark.parametrize("v_left,v_right", WHEEL_SPEEDS)
def test_integrate_arcs_lands_on_the_analytic_circle(v_left: float, v_right: float, dt: float) -> None:
    s, a = _constant_arcs(v_left, v_right, dt)
    end = integrate_arcs(START, s, a)[-1]
    v, omega = twist_from_wheel_speeds(v_left, v_right, TRACK)
    expected = analytic_pose(START, float(v), float(omega), 10.0)
    assert math.hypot(*(end - expected)[:2]) < 1e-9
    assert abs(end[2] - expected[2]) < 1e-12


@pytest.mark.parametrize("dt", DTS)
@pytest.mark.parametrize("v_left,v_right", WHEEL_SPEEDS)
def test_stepwise_increments_land_on_the_analytic_circle(v_left: float, v_right: float, dt: float) -> None:
    s, a = _constant_arcs(v_left, v_right, dt)
    increment = arc_increment(s[0], a[0])
    current = START
    for _ in range(len(s)):
        current = apply_increment(current, increment)
    v, omega = twist_from_wheel_speeds(v_left, v_right, TRACK)
    expected = analytic_pose(START, float(v), float(omega), 10.0)
    assert math.hypot(*(current - expected)[:2]) < 1e-9
    # plain `theta += alpha` rounds at every step: 10,000 steps to ~20 rad drift by up to ~1e-11
    assert abs(current[2] - expected[2]) < 1e-10


@pytest.mark.parametrize("v_left,v_right", ((0.1, 0.3), (0.4483, 0.4)))
def test_euler_integration_of_the_same_circle_is_centimetres_off(v_left: float, v_right: float) -> None:
    """What peers do (x += v cos(theta) dt): at dt = 0.1 s, 10 s of a circle end 15-26 mm off,
    first order in dt, where the exact arc is off by rounding only."""
    v, omega = (float(q) for q in twist_from_wheel_speeds(v_left, v_right, TRACK))
    expected = analytic_pose(START, v, omega, 10.0)
    errors = []
    for dt in (0.1, 0.05):
        euler = START.copy()
        for _ in range(round(10.0 / dt)):
            euler = euler + np.array([v * math.cos(euler[2]) * dt, v * math.sin(euler[2]) * dt, omega * dt])
        errors.append(math.hypot(*(euler - expected)[:2]))
    assert errors[0] > 0.01
    assert errors[1] == pytest.approx(errors[0] / 2, rel=0.1)  # first order
    s, a = _constant_arcs(v_left, v_right, 0.1)
    assert math.hypot(*(integrate_arcs(START, s, a)[-1] - expected)[:2]) < 1e-9 < errors[0] / 1e7


@given(st.lists(st.tuples(wheel_arc, wheel_arc), min_size=1, max_size=50), pose)
@settings(max_examples=60)
def test_integrate_arcs_equals_stepwise_application(wheels: list[tuple[float, float]], start: np.ndarray) -> None:
    s_l, s_r = np.array(wheels).T
    s, a = wheel_arcs_to_arc(s_l, s_r, TRACK)
    poses = integrate_arcs(start, s, a)
    current = start
    for k in range(len(s)):
        current = apply_increment(current, wheel_increment(s_l[k], s_r[k], TRACK))
        np.testing.assert_allclose(poses[k], current, rtol=0, atol=1e-12 * (1 + np.abs(start).max()))


# --- continuity through the straight line ------------------------------------------------------


@pytest.mark.parametrize("s", (1.0, -0.3, 1e-3))
@pytest.mark.parametrize("a", (1e-15, -1e-15, 1e-9, -1e-9, 1e-5))
def test_nearly_straight_arcs_differ_from_the_line_by_order_alpha(s: float, a: float) -> None:
    line = arc_increment(s, 0.0)
    np.testing.assert_array_equal(line, [s, 0.0, 0.0])
    near = arc_increment(s, a)
    # dx = s sin(a)/a, dy = s (1 - cos a)/a: s*a/2 sideways and s*a^2/6 shorter, nothing else
    assert near[1] == pytest.approx(s * a / 2, rel=1e-10)
    assert abs(near[0] - s) <= abs(s) * (a * a / 6 + EPS)
    assert near[0] == pytest.approx(s * (1 - a * a / 6), rel=EPS)
    assert near[2] == a


@given(arc_length, st.floats(-1.0, 1.0), st.floats(-1.0, 1.0))
@settings(max_examples=200)
def test_arc_increment_is_lipschitz_in_alpha(s: float, a1: float, a2: float) -> None:
    """|d position / d alpha| <= |s|/2 everywhere, across 0 and the series/trig switch at |alpha| = 0.5:
    no jump, no branch artefact."""
    d = arc_increment(s, a1) - arc_increment(s, a2)
    assert math.hypot(d[0], d[1]) <= abs(s) * (abs(a1 - a2) / 2 + 8 * EPS)


@given(finite, finite)
@settings(max_examples=300)
def test_no_nan_and_no_fp_warning_for_any_finite_input(s: float, a: float) -> None:
    with np.errstate(over="raise", invalid="raise", divide="raise"):  # underflow is harmless
        inc = arc_increment(s, a)
        fw = firmware_increment(s, a)
        sin_h, cos_h, sinc_h = half_angle_terms(a)
    assert np.isfinite(inc).all() and np.isfinite(fw).all()
    assert np.isfinite([sin_h, cos_h, sinc_h]).all()
    assert math.hypot(inc[0], inc[1]) <= abs(s)  # the chord never exceeds the arc
    assert inc[2] == a


@pytest.mark.parametrize("s,a", ((0.0, 0.7), (0.0, -3.0), (0.0, 0.0), (-0.2, 0.0), (-0.2, 0.4), (-0.2, -0.4)))
def test_spin_and_reversing(s: float, a: float) -> None:
    inc = arc_increment(s, a)
    if s == 0.0:
        np.testing.assert_array_equal(inc[:2], 0.0)  # a spin on the spot does not move the axle centre
    else:
        # reversing with the same heading change is the forward arc mirrored through the start
        forward = arc_increment(-s, a)
        np.testing.assert_allclose(inc[:2], -forward[:2], rtol=0, atol=1e-17)
    assert inc[2] == a


def test_half_angle_terms_are_continuous_across_the_series_switch() -> None:
    """The series (|alpha/2| <= 0.25) and numpy's sin/cos agree to 1e-15 relative on both sides."""
    h = np.concatenate(
        (
            0.25 + np.arange(-64, 65) * 2.0**-54,  # ulps around the switch
            np.linspace(-0.3, 0.3, 6001),
            np.geomspace(1e-300, 0.25, 301),
            -np.geomspace(1e-300, 0.25, 301),
        )
    )
    sin_h, cos_h, sinc_h = half_angle_terms(2 * h)
    assert np.all(np.abs(sin_h - np.sin(h)) <= 1e-15 * np.abs(np.sin(h)))
    assert np.all(np.abs(cos_h - np.cos(h)) <= 1e-15 * np.cos(h))
    nonzero = h != 0
    reference = np.sin(h[nonzero]) / h[nonzero]
    assert np.all(np.abs(sinc_h[nonzero] - reference) <= 1e-15 * reference)
    below, at, above = half_angle_terms(np.array([np.nextafter(0.5, 0), 0.5, np.nextafter(0.5, 1)]))[0]
    assert below <= at <= above and above - below <= 4 * EPS


def test_half_angle_terms_at_zero() -> None:
    sin_h, cos_h, sinc_h = half_angle_terms(np.array([0.0, -0.0]))
    np.testing.assert_array_equal(sin_h, 0.0)
    np.testing.assert_array_equal(cos_h, 1.0)
    np.testing.assert_array_equal(sinc_h, 1.0)


# --- an arc is a circle ------------------------------------------------------------------------


@given(arc_length, alpha)
@settings(max_examples=200)
def test_arc_end_point_lies_on_the_circle_through_the_start(s: float, a: float) -> None:
    """Centre (0, s/a), radius |s/a|: dx^2 + (dy - s/a)^2 = (s/a)^2, i.e. a (dx^2 + dy^2) = 2 s dy
    (division-free, so it also holds on the straight line); heading change a; chord <= arc."""
    dx, dy, dth = arc_increment(s, a)
    assert dth == a
    assert abs(a * (dx * dx + dy * dy) - 2 * s * dy) <= 16 * EPS * s * s * max(abs(a), 1.0) + 1e-300  # (underflow)
    # the chord length is 2 R sin(a/2)
    assert math.hypot(dx, dy) == pytest.approx(abs(s * sinc(a / 2)), rel=1e-14)


@given(arc_length, alpha, pose)
@settings(max_examples=200)
def test_arc_step_is_a_rotation_about_the_icc(s: float, a: float, start: np.ndarray) -> None:
    """Seed 003 eq 4: the new pose is the old one rotated by omega*dt about the ICC."""
    if abs(a) < 1e-3:
        return  # the ICC is far away: the rotation form is ill-conditioned, covered by continuity
    radius = s / a
    centre = start[:2] + radius * np.array([-math.sin(start[2]), math.cos(start[2])])
    expected = rotate_about(start[:2], centre, a)
    end = apply_increment(start, arc_increment(s, a))
    np.testing.assert_allclose(end[:2], expected, rtol=0, atol=1e-12 * (1 + abs(radius) + np.abs(start[:2]).max()))
    assert end[2] == start[2] + a


@given(st.floats(-5.0, 5.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0))
@settings(max_examples=200)
def test_equal_curvature_arcs_compose_to_one_arc(kappa: float, s1: float, s2: float) -> None:
    a1, a2 = kappa * s1, kappa * s2
    np.testing.assert_allclose(compose(arc_increment(s1, a1), arc_increment(s2, a2)), arc_increment(s1 + s2, a1 + a2), rtol=0, atol=1e-14)


@given(st.floats(-3.0, 3.0), st.floats(-3.0, 3.0))
def test_spins_compose(a1: float, a2: float) -> None:
    np.testing.assert_allclose(compose(arc_increment(0.0, a1), arc_increment(0.0, a2)), [0.0, 0.0, a1 + a2], atol=1e-15)


# --- SE(2) identities --------------------------------------------------------------------------


@given(arc_length, arc_length, alpha)
@settings(max_examples=200)
def test_se2_exp_log_round_trip(vx: float, vy: float, w: float) -> None:
    twist = np.array([vx, vy, w])
    increment = se2_exp(twist)
    np.testing.assert_allclose(se2_log(increment), twist, rtol=0, atol=1e-13)
    np.testing.assert_allclose(se2_exp(se2_log(increment)), increment, rtol=0, atol=1e-13)


@given(arc_length, alpha)
def test_se2_exp_of_a_forward_twist_is_the_arc(s: float, a: float) -> None:
    np.testing.assert_allclose(se2_exp(np.array([s, 0.0, a])), arc_increment(s, a), rtol=0, atol=1e-16)


@given(pose, arc_length, arc_length, alpha)
@settings(max_examples=200)
def test_relative_increment_inverts_apply_increment(start: np.ndarray, dx: float, dy: float, dth: float) -> None:
    increment = np.array([dx, dy, dth])
    end = apply_increment(start, increment)
    np.testing.assert_allclose(relative_increment(start, end), increment, rtol=0, atol=1e-13)
    np.testing.assert_allclose(apply_increment(start, relative_increment(start, end)), end, rtol=0, atol=1e-13)


# --- the firmware's variant ---------------------------------------------------------------------


@given(arc_length, alpha)
@settings(max_examples=200)
def test_firmware_step_is_the_exact_chord_rotated_by_half_alpha(s: float, a: float) -> None:
    """The firmware lays the chord along the end heading: its end point is the exact one rotated by
    a/2 about the start; in the exact chord's frame the error is s_hat*(cos(a/2) - 1) along and
    s_hat*sin(a/2) across; the heading is right."""
    exact, firmware = arc_increment(s, a), firmware_increment(s, a)
    assert firmware[2] == exact[2] == a
    np.testing.assert_allclose(firmware[:2], rotate_about(exact[:2], np.zeros(2), a / 2), rtol=0, atol=1e-15)
    chord = s * sinc(a / 2)
    direction = exact[:2] / chord if chord else np.array([1.0, 0.0])
    error = firmware[:2] - exact[:2]
    along = error @ direction
    across = direction[0] * error[1] - direction[1] * error[0]
    rounding = 4 * EPS * abs(s)  # the errors are differences of two end points of size |s|
    assert across == pytest.approx(chord * math.sin(a / 2), rel=1e-12, abs=rounding)
    assert along == pytest.approx(chord * (math.cos(a / 2) - 1), rel=1e-12, abs=rounding)


@pytest.mark.parametrize("v_left,v_right", ((0.1, 0.2), (0.3, -0.1), (-0.2, -0.1), (0.4483, 0.3)))
def test_firmware_path_is_the_exact_circle_rotated_about_the_start(v_left: float, v_right: float) -> None:
    """Constant wheel speeds, dt = 10 ms: every firmware step is the exact step rotated by a/2 (the
    headings agree), so after k steps the firmware sits on the exact circle rotated by a/2 about the
    start. The end error after k steps is 2|sin(a/4)| * |chord of k steps| = 4|R sin(a/4) sin(k a/2)|:
    zero after a full turn, largest (~ one step length) after half a turn. No drift, a wobble."""
    dt = 0.01
    v, omega = (float(q) for q in twist_from_wheel_speeds(v_left, v_right, TRACK))
    s, a = v * dt, omega * dt
    radius = s / a
    steps = round(2 * math.pi / abs(a)) * 2  # two full turns
    exact = integrate_arcs(START, np.full(steps, s), np.full(steps, a))
    firmware = START
    firmware_path = []
    for _ in range(steps):
        firmware = apply_increment(firmware, firmware_increment(s, a))
        firmware_path.append(firmware)
    firmware_path = np.array(firmware_path)
    np.testing.assert_allclose(firmware_path[:, 2], exact[:, 2], rtol=0, atol=1e-12)
    np.testing.assert_allclose(firmware_path[:, :2], rotate_about(exact[:, :2], START[:2], a / 2), rtol=0, atol=1e-12)
    k = np.arange(1, steps + 1)
    predicted = np.abs(4 * radius * math.sin(a / 4) * np.sin(k * a / 2))
    errors = np.hypot(*(firmware_path[:, :2] - exact[:, :2]).T)
    np.testing.assert_allclose(errors, predicted, rtol=0, atol=1e-12)
    # the largest error is about one step's chord, whatever the radius
    assert errors.max() == pytest.approx(abs(s), rel=1e-3)


@given(st.lists(st.tuples(wheel_arc, wheel_arc), min_size=1, max_size=40), pose)
@settings(max_examples=60)
def test_firmware_path_for_varying_arcs(wheels: list[tuple[float, float]], start: np.ndarray) -> None:
    """In general each firmware step is the exact world step rotated by its own a_j/2."""
    s_l, s_r = np.array(wheels).T
    s, a = wheel_arcs_to_arc(s_l, s_r, TRACK)
    exact = np.concatenate((start[None], integrate_arcs(start, s, a)))
    firmware = start
    predicted = start[:2].copy()
    for j in range(len(s)):
        firmware = apply_increment(firmware, firmware_increment(s[j], a[j]))
        predicted = predicted + rotate_about(exact[j + 1, :2] - exact[j, :2], np.zeros(2), a[j] / 2)
        np.testing.assert_allclose(firmware[:2], predicted, rtol=0, atol=1e-12 * (1 + np.abs(start[:2]).max()))
        assert firmware[2] == pytest.approx(exact[j + 1, 2], abs=1e-12)


@given(pose, pose)
def test_relative_pose_is_relative_increment_of_one_pair(start, end) -> None:
    """The scalar form gives the numpy form's numbers (the same operations; the tolerance allows
    a libm whose sine rounds differently from numpy's in the last bit, times coordinates of metres)."""
    np.testing.assert_allclose(relative_pose(start, end), relative_increment(np.array(start), np.array(end)), rtol=0, atol=1e-12)


@given(pose, arc_length, alpha, st.booleans())
def test_scalar_advance_is_the_array_forms_arc(start, s, a, end_heading) -> None:
    """`advance` (plain floats, for behaviours that step one robot at a time) lands where the array
    form does: the start pose moved by `arc_increment` (mid-angle) or `firmware_increment` (end
    heading). The two compute different sums (one rotates the increment by the heading, the other
    takes cos and sin of the sum of angles), so they agree to rounding: a few ulps of the
    coordinates and of the step (1e-12 m with coordinates up to 100 m and steps up to 1 m)."""
    increment = (firmware_increment if end_heading else arc_increment)(s, a)
    expected = apply_increment(start, increment)
    np.testing.assert_allclose(advance(start, s, a, end_heading), expected, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(advance_floats(tuple(start.tolist()), s, a, end_heading), advance(start, s, a, end_heading))


@given(st.one_of(angle, finite))
def test_wrap_angle_of_a_float_is_the_array_forms(turn) -> None:
    """`wrap_angle` of a Python float takes its own path (no numpy call) to the array form's number,
    exactly: the same operations on the same doubles."""
    assert wrap_angle(turn) == float(wrap_angle(np.array(turn)))
