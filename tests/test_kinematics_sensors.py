"""Encoders, quantisation with carry, and the mouse sensor (seed 002 §2; ctsim-reference §1)."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from printed import places
from strategies import (
    EPS,
    TRACK,
    WHEEL_RADIUS,
    floats,
    mount_point,
    sinc,
    track_width,
    wheel_arc,
)

from bots.ctbot import CTBOT
from sim.kinematics import (
    MouseEstimator,
    UnobservableRotation,
    arc_increment,
    arcs_from_ticks,
    counts_per_metre,
    mouse_count_series,
    mouse_counts,
    mouse_displacement,
    mouse_displacement_from_increment,
    quantize,
    quantize_series,
    ticks_from_arc_series,
    ticks_from_arcs,
    ticks_per_metre,
    wheel_arcs_to_arc,
    wheel_increment,
)
from sim.kinematics.encoders import CTBOT_TICKS_PER_REV

carry = floats(0.0, 1.0, exclude_max=True)
# dyadic values (multiples of 2^-12, below 2^10): every sum of a few thousand is exact in float64,
# so quantize and quantize_series must agree with exact rational arithmetic to the last count
DYADIC = 2.0**-12
dyadic = st.integers(-(2**22), 2**22).map(lambda k: k * DYADIC)
dyadic_carry = st.integers(0, 2**12 - 1).map(lambda k: k * DYADIC)


def _repeated_quantize(values: np.ndarray, carry0: float) -> tuple[np.ndarray, float]:
    counts, c = [], carry0
    for value in values:
        n, c = quantize(value, c)
        assert 0.0 <= c < 1.0
        counts.append(int(n))
    return np.array(counts), float(c)


# --- encoders ----------------------------------------------------------------------------------


def test_ctbot_encoder_constants() -> None:
    """60 ticks per revolution of a 56.7 mm wheel: c't-Sim's 0.1781283 m of rim, 2.9688 mm per tick."""
    assert CTBOT.encoders.ticks_per_rev == CTBOT_TICKS_PER_REV == 60
    per_metre = ticks_per_metre(WHEEL_RADIUS)
    assert per_metre * 0.1781283 == pytest.approx(60, rel=1e-7)  # pi * 56.7 mm, rounded to 0.1 um
    assert 1 / per_metre == pytest.approx(0.0029688, rel=1e-5)
    ticks, rest = ticks_from_arcs(math.pi * CTBOT.wheel_diameter, 0.0, WHEEL_RADIUS)
    assert int(ticks) == 60 and rest == pytest.approx(0.0, abs=1e-12)
    ticks, rest = ticks_from_arcs(0.1781283, 0.5, WHEEL_RADIUS)
    assert int(ticks) == 60 and rest == pytest.approx(0.5 - (60 - per_metre * 0.1781283), abs=1e-12)
    # ten revolutions backwards in 10 ms steps at full speed (1.51 ticks per step): -600 ticks
    steps = 400
    series, _ = ticks_from_arc_series(np.full(steps, -10 * 0.1781283 / steps), 0.5, WHEEL_RADIUS)
    assert series.sum() == -600


@given(wheel_arc, carry, floats(0.01, 0.1), st.sampled_from((60, 120, 500)))
@settings(max_examples=200)
def test_arc_to_ticks_to_arc_within_one_tick(s_wheel: float, carry0: float, radius: float, per_rev: int) -> None:
    ticks, rest = ticks_from_arcs(s_wheel, carry0, radius, per_rev)
    tick_length = 2 * math.pi * radius / per_rev
    back = float(arcs_from_ticks(ticks, radius, per_rev))
    assert abs(back - s_wheel) < tick_length * (1 + 1e-12)
    # nothing is lost: the ticks and the change of the carry account for the whole arc
    assert back + (rest - carry0) * tick_length == pytest.approx(s_wheel, abs=1e-15)


@given(st.lists(wheel_arc, min_size=1, max_size=300), carry)
@settings(max_examples=60)
def test_encoders_over_a_trajectory_stay_within_one_tick(arcs: list[float], carry0: float) -> None:
    ticks, _ = ticks_from_arc_series(np.array(arcs), carry0, WHEEL_RADIUS)
    tick_length = 1 / ticks_per_metre(WHEEL_RADIUS)
    assert abs(ticks.sum() * tick_length - math.fsum(arcs)) <= tick_length * (1 + 1e-9)


# --- quantisation with carry -----------------------------------------------------------------


@given(st.lists(dyadic, min_size=1, max_size=400), dyadic_carry)
@settings(max_examples=100)
def test_quantize_never_drifts_exact(values: list[float], carry0: float) -> None:
    """Sum of counts over any number of steps, either sign, = floor(total + carry0) exactly."""
    exact_total = sum(Fraction(v) for v in values) + Fraction(carry0)
    counts, final = _repeated_quantize(np.array(values), carry0)
    assert counts.sum() == math.floor(exact_total)
    assert Fraction(final) == exact_total - math.floor(exact_total)
    series, series_final = quantize_series(np.array(values), carry0)
    np.testing.assert_array_equal(series, counts)
    assert series_final == final


@given(st.lists(floats(-1e3, 1e3), min_size=1, max_size=400), carry)
@settings(max_examples=100)
def test_quantize_never_drifts_floats(values: list[float], carry0: float) -> None:
    """With arbitrary floats only the rounding of each step's `value + carry` remains: counts plus
    carry track the exact total to ~T ulp, so the count sum is floor(total + carry0) unless the total
    lies within that rounding of an integer."""
    total = math.fsum(values) + carry0
    counts, final = _repeated_quantize(np.array(values), carry0)
    rounding = len(values) * 4 * EPS * (1e3 + abs(total))
    assert abs(counts.sum() + final - total) <= rounding
    assume(abs(total - round(total)) > rounding)
    assert counts.sum() == math.floor(total)


@given(st.lists(floats(-50.0, 50.0), min_size=1, max_size=400), carry)
@settings(max_examples=100)
def test_quantize_series_matches_repeated_quantize(values: list[float], carry0: float) -> None:
    """The series floors a cumulative sum, the loop rounds value + carry step by step: the two
    differ only where a running total lies within rounding of an integer, and then by one count in
    that step and the opposite count later: the running count sums never differ by more than one,
    and agree again at the end unless the final total itself sits on such a boundary."""
    counts, final = _repeated_quantize(np.array(values), carry0)
    series, series_final = quantize_series(np.array(values), carry0)
    assert 0.0 <= series_final < 1.0
    differences = np.cumsum(series) - np.cumsum(counts)
    assert np.all(np.abs(differences) <= 1)
    assert np.count_nonzero(series != counts) <= 2 * np.count_nonzero(differences)
    if differences[-1] == 0:
        assert series_final == pytest.approx(final, abs=len(values) * 200 * EPS)


@pytest.mark.parametrize("value,carry0", ((-1e-20, 0.0), (-1e-17, 0.0), (-3.0 - 1e-16, 0.0), (0.75, 0.25 - 1e-17)))
def test_quantize_carry_stays_below_one(value: float, carry0: float) -> None:
    """A total just below an integer: total - floor(total) rounds to 1.0; the carry must stay in
    [0, 1) (it did not: quantize(-1e-20, 0) gave (-1, 1.0)) and the counts still account for it."""
    n, c = quantize(value, carry0)
    assert 0.0 <= c < 1.0
    assert n + c == pytest.approx(value + carry0, abs=1e-15)
    series, series_final = quantize_series(np.array([0.5, value - 0.5]), carry0)
    assert 0.0 <= series_final < 1.0
    assert series.sum() + series_final == pytest.approx(value + carry0, abs=1e-15)


# --- the mouse sensor ------------------------------------------------------------------------


@given(wheel_arc, wheel_arc, floats(0.005, 0.1))
@settings(max_examples=200)
def test_seed_002_mouse_relations_on_the_centre_line(s_left: float, s_right: float, lever: float) -> None:
    """Sensor on the centre line |MP| behind the axle (c't-Bot: 15 mm). Seed: X = alpha*|MP| with
    c't-Sim's x to the right, Y = alpha*r = s. Ours reads (forward, left): forward = Y, left = -X.
    Inverse: alpha = X/|MP|, r = Y/alpha."""
    s, a = (float(q) for q in wheel_arcs_to_arc(s_left, s_right, TRACK))
    forward, left = mouse_displacement(s, a, np.array([-lever, 0.0]))
    x_seed, y_seed = -left, forward
    assert x_seed == pytest.approx(a * lever, rel=1e-15, abs=1e-300)
    assert y_seed == s
    if a != 0.0:
        radius = s / a  # seed 002 eq 1.4, signed
        assert y_seed == pytest.approx(a * radius, rel=1e-15, abs=1e-300)
        assert x_seed / lever == pytest.approx(a, rel=1e-15)
        assert y_seed / (x_seed / lever) == pytest.approx(radius, rel=1e-14)
    # c't-Sim puts the chord in Y: short by s * (1 - sinc(a/2)) ~ s a^2 / 24, which we avoid
    chord = s * sinc(a / 2)
    # `chord` is rounded twice (sinc to half an ulp of 1, the product to half an ulp of s), the
    # difference with s once more: each side is the exact value to within 2 ulp of s
    rounding = 2 * np.spacing(abs(s))
    assert forward - chord == pytest.approx(s * (1 - sinc(a / 2)), abs=2 * rounding)
    assert abs(forward - chord) <= abs(s) * a * a / 24 + rounding


def test_mouse_full_turn_is_1484_counts() -> None:
    """c't-Bot MOUSE_FULL_TURN: 2*pi * 15 mm * 400 dpi / 25.4 = 1484.2 counts for a turn on the spot,
    also when counted step by step with the carry (10 ms steps at full speed)."""
    mount = np.array(CTBOT.mouse.mount)
    per_turn = 2 * math.pi * abs(mount[0]) * float(counts_per_metre(CTBOT.mouse.dpi))
    assert per_turn == pytest.approx(1484.217, abs=places(3))
    counts, _ = mouse_counts(mouse_displacement(0.0, -2 * math.pi, mount), np.zeros(2), CTBOT.mouse.dpi)
    np.testing.assert_array_equal(counts, [0, 1484])  # clockwise, sensor behind: alpha*m_x > 0
    steps = 700  # 0.8966 m/s of wheel difference at full speed: about 700 steps of 10 ms per turn
    per_step = mouse_displacement(np.zeros(steps), np.full(steps, -2 * math.pi / steps), mount)
    series, _ = mouse_count_series(per_step, np.zeros(2), CTBOT.mouse.dpi)
    np.testing.assert_array_equal(series.sum(axis=0), [0, 1484])
    # counter-clockwise the counts floor towards -inf: -1485 with 0.78 carried
    counts, rest = mouse_counts(mouse_displacement(0.0, 2 * math.pi, mount), np.zeros(2), CTBOT.mouse.dpi)
    np.testing.assert_array_equal(counts, [0, -1485])
    assert rest[1] == pytest.approx(1485 - per_turn)


@given(wheel_arc, wheel_arc, track_width, mount_point())
@settings(max_examples=200)
def test_mouse_round_trip_without_quantisation(s_left: float, s_right: float, track: float, mount: np.ndarray) -> None:
    """arc -> ground displacement -> (real-valued) counts -> MouseEstimator reproduces the arc."""
    s, a = wheel_arcs_to_arc(s_left, s_right, track)
    dpi = 400.0
    counts = mouse_displacement(s, a, mount) * counts_per_metre(dpi)
    estimator = MouseEstimator(mount=tuple(mount), dpi=dpi)
    s_back, a_back = estimator.arc(counts)
    assert a_back == pytest.approx(a, rel=1e-14, abs=1e-300)
    assert s_back == pytest.approx(s, abs=4 * EPS * (abs(s) + abs(a * mount[1])) + 1e-300)
    np.testing.assert_allclose(estimator.increment(counts), wheel_increment(s_left, s_right, track), rtol=0, atol=1e-15)


@given(wheel_arc, wheel_arc, track_width, mount_point(), st.sampled_from((400.0, 800.0, 1e6, 1e9)))
@settings(max_examples=200)
def test_mouse_round_trip_through_counts_within_the_quantisation_bound(
    s_left: float, s_right: float, track: float, mount: np.ndarray, dpi: float
) -> None:
    """Counts floor each axis, so each reads less than one count (q = 25.4 mm/dpi) short: then
    |d alpha| < q/|m_x|, |d s| < q (1 + |m_y|/|m_x|), and the pose increment moves by at most
    |d s| + |s| |d alpha| / 2 (|d pos/d s| <= 1, |d pos/d alpha| <= |s|/2). At 1e9 dpi that is nm."""
    s, a = (float(q) for q in wheel_arcs_to_arc(s_left, s_right, track))
    counts, _ = mouse_counts(mouse_displacement(s, a, mount), np.zeros(2), dpi)
    estimator = MouseEstimator(mount=tuple(mount), dpi=dpi)
    q = 0.0254 / dpi
    d_alpha = q / abs(mount[0])
    d_s = q + abs(mount[1]) * d_alpha
    s_back, a_back = estimator.arc(counts)
    slack = 1 + 1e-9
    assert abs(a_back - a) <= d_alpha * slack
    assert abs(s_back - s) <= d_s * slack
    error = estimator.increment(counts) - arc_increment(s, a)
    assert abs(error[2]) <= d_alpha * slack
    assert math.hypot(error[0], error[1]) <= (d_s + (abs(s) + d_s) * d_alpha / 2) * slack + 1e-15


@given(wheel_arc, wheel_arc, track_width, mount_point())
@settings(max_examples=200)
def test_mouse_displacement_from_increment_matches_the_arc(s_left: float, s_right: float, track: float, mount: np.ndarray) -> None:
    s, a = wheel_arcs_to_arc(s_left, s_right, track)
    np.testing.assert_allclose(
        mouse_displacement_from_increment(arc_increment(s, a), mount), mouse_displacement(s, a, mount), rtol=0, atol=1e-15
    )


@pytest.mark.parametrize("mount", ((0.0, 0.0), (0.0, 0.03), (-0.0, -0.02), (5e-5, 0.0), (math.nan, 0.0)))
def test_mount_on_the_axle_line_is_rejected(mount: tuple[float, float]) -> None:
    with pytest.raises(UnobservableRotation, match="axle line"):
        MouseEstimator(mount=mount)
    assert issubclass(UnobservableRotation, ValueError)


@pytest.mark.parametrize("dpi", (0.0, -400.0, math.nan, math.inf))
def test_mouse_resolution_must_be_positive(dpi: float) -> None:
    with pytest.raises(ValueError, match="dpi"):
        MouseEstimator(mount=(-0.015, 0.0), dpi=dpi)


@given(st.lists(st.tuples(wheel_arc, wheel_arc), min_size=1, max_size=300), mount_point())
@settings(max_examples=40)
def test_mouse_count_series_never_drifts(wheels: list[tuple[float, float]], mount: np.ndarray) -> None:
    s_l, s_r = np.array(wheels).T
    s, a = wheel_arcs_to_arc(s_l, s_r, TRACK)
    displacement = mouse_displacement(s, a, mount)
    series, _ = mouse_count_series(displacement, np.zeros(2), 400.0)
    exact = displacement.sum(axis=0) * float(counts_per_metre(400.0))
    assert np.all(np.abs(series.sum(axis=0) - exact) <= 1 + 1e-9)
    # and step by step the same, to one count at most in the running sums
    c = np.zeros(2)
    running = np.zeros(2, dtype=np.int64)
    for k in range(len(s)):
        n, c = mouse_counts(displacement[k], c, 400.0)
        running += n
        assert np.all(np.abs(running - series[: k + 1].sum(axis=0)) <= 1)
