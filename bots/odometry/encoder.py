"""The wheel encoders' odometry through the exact arc, and its compiled step."""

from __future__ import annotations

import numba
import numpy as np

from bots.odometry.base import ArcOdometry
from bots.odometry.layout import ESTIMATE, NODES, PLANE, SIGMAS
from bots.odometry.propagation import END_HEADING, MID_ANGLE, carry_noise, lay_point, nodes_of, noise_of, propagate, wheel_terms, wheel_variances
from bots.readings import Readings
from sim.kinematics.batch import INNER, chord_of


@numba.njit(cache=True, error_model="numpy")
def encoder_step(p: np.void, heading: float, cov: np.ndarray, left: float, right: float, end_heading: bool, work: np.ndarray) -> tuple[float, float]:
    """Encoder odometry: the increment of `left`, `right` ticks; `cov` propagated from `heading`
    (`work`: scratch, `workspace`)."""
    s_left, s_right = left * p.tick_left, right * p.tick_right
    s, alpha = 0.5 * (s_left + s_right), (s_right - s_left) / p.track
    jac, noise = work[PLANE.jac, :2, :], work[PLANE.noise, :2, :2]
    var_left, var_right = wheel_variances(p, s_left, s_right)
    wheel_terms(s_left, s_right, alpha, p.track, var_left, var_right, jac, noise)
    propagate(cov, heading, s, alpha, END_HEADING if end_heading else MID_ANGLE, jac, noise, work)
    return s, alpha


@numba.njit(cache=True, error_model="numpy", inline="always")
def sigma_arc(p: np.void, point: int, left: float, right: float) -> tuple[float, float]:
    """The arc (s, alpha) of these ticks as sigma point `point` of the encoders' calibration sees
    it: it believes the left wheel, the right wheel and the track off by one node each (`NODES`,
    its base-3 digits: `nodes_of`), so its wheels roll (1 + k) times the believed arc and it turns
    over (1 + k) times the believed track, exactly, however far its heading strays."""
    left_node, right_node, track_node = nodes_of(point)
    s_left = left * p.tick_left * (1.0 + NODES[left_node] * p.wheel_std)
    s_right = right * p.tick_right * (1.0 + NODES[right_node] * p.wheel_std)
    track = p.track * (1.0 + NODES[track_node] * p.track_std)
    return 0.5 * (s_left + s_right), (s_right - s_left) / track


@numba.njit(cache=True, error_model="numpy")
def sigma_encoders(p: np.void, sigmas: np.ndarray, noises: np.ndarray, left: float, right: float, share: float, noise: np.ndarray,
                   turns: np.ndarray) -> None:  # fmt: skip
    """Lay these ticks on every sigma point of the encoders' calibration (`sigma_arc`) along
    heading + share * alpha, each point's random part `noises` (COVARIANCE_FIELDS, SIGMAS) carried
    with the step's `noise` (2, 2; `wheel_terms`), in place (`lay_point`, `carry_noise`; `turns`
    (3, SIGMAS): scratch)."""
    for i in range(SIGMAS):
        s, alpha = sigma_arc(p, i, left, right)
        lay_point(sigmas, turns, i, s, chord_of(s, alpha), alpha, share)
    carry_noise(noises, turns, share, noise_of(noise))


@numba.njit(cache=True, error_model="numpy", **INNER)
def sigma_encoders_both(p: np.void, st: np.void, left: float, right: float, noise: np.ndarray) -> None:
    """`sigma_encoders` on the encoders' sigma points (along the mid-angle) and the firmware's
    (along the end heading) of a STATE row `st` at once: the same ticks through the same nodes, so
    each point's arc and chord are worked out once for both (the same operations: the same bits)."""
    mid, end, turns = st.sigmas[ESTIMATE.encoders], st.sigmas[ESTIMATE.firmware], st.turns
    for i in range(SIGMAS):
        s, alpha = sigma_arc(p, i, left, right)
        chord = chord_of(s, alpha)
        lay_point(mid, turns[ESTIMATE.encoders], i, s, chord, alpha, MID_ANGLE)
        lay_point(end, turns[ESTIMATE.firmware], i, s, chord, alpha, END_HEADING)
    entries = noise_of(noise)
    carry_noise(st.sigma_noises[ESTIMATE.encoders], turns[ESTIMATE.encoders], MID_ANGLE, entries)
    carry_noise(st.sigma_noises[ESTIMATE.firmware], turns[ESTIMATE.firmware], END_HEADING, entries)


class EncoderOdometry(ArcOdometry):
    """Wheel encoders through the exact arc: ticks -> wheel arcs -> pose increment (eqs 1.3, 1.12).
    Covariance: each wheel's arc has variance (slip_var + tick_rate * tick) * |s| per step
    (first order), and the wheel scales and track are unknown by their believed size
    (`bots.uncertainty`), carried by 26 sigma points, every combination of three nodes of each
    (`ArcOdometry`, `bots.odometry.layout.SIGMAS`). The random part is carried along each point's
    own path as well as the estimate's (`carry_noise`) and reported as their mean, weighed as the
    points (`add_point_noise`): a heading error turns every later move, and a robot whose
    calibration turns its heading 100-150 degrees from the estimate's spreads its random error
    across its own path. Carried along the estimate's path alone, the random part read a mean
    NEES of 3.08 / 3.44 / 8.18 against its own covariance at 10 / 50 / 100 % of 240 drawn maze
    runs of solve_maze; so, 3.00 / 3.15 / 3.21.

    Where the heading ends tens of degrees off (47 degrees of standard deviation at the end of a
    maze run) the errors lie on a curve no Gaussian describes: the points give the covariance of
    that curve, right in expectation on every path (each of the 240 paths with 200 calibrations
    drawn from the belief, no random noise: mean NEES 3.00 / 3.03 / 3.13), and the robots'
    calibrations are the belief's given their paths; but a robot far out in its belief lies well
    off the ellipse (seed 212's own calibration, 2.9 standard deviations in the wheels'
    difference, reads NEES 50 at the end without any random noise) while most lie well inside it
    (median NEES 1.43 over the 240, chi-square's 2.37). The mean is carried by the rare far-out
    robots (the 7 of the 240 whose wheels differ by more than 2.4 standard deviations, 1.5 % of
    robots in general, carry 43 % of the 240's sum), so a mean over 40 strays both ways beyond
    the interval of 40 (2.11 to 7.68 on six sets): calibration alone, its covariance exact, puts
    55 % of sets of 40 outside at the end (docs/odometry.md, "Why sets of 40 stray").

    geometry: the believed wheel diameters and track; None = the robot's belief's (`Geometry.believed`:
    the nominal ones unless a calibration corrected them)."""

    name = "encoders"
    sigma_count = SIGMAS
    caveat = ("one robot's wheels and track are off the same in every run: its mean NEES over runs says where they lie in "
              "its belief (the realistic c't-Bot's stated belief: too cautious; the one `ctsim umbmark` measures: inside), "
              "not whether the covariance holds over the robots it describes; a heading ending tens of degrees off puts the "
              "position where no Gaussian does, so a mean NEES over 40 robots at a run's end strays both ways")  # fmt: skip

    def step(self, readings: Readings) -> tuple[float, float]:
        left, right = readings.encoder_ticks.tolist()
        arc = encoder_step(self.params, float(self.pose[2]), self.errors, float(left), float(right), self.end_heading, self.work)
        sigma_encoders(self.params, self.sigmas, self.noises, float(left), float(right), END_HEADING if self.end_heading else MID_ANGLE, self.work[PLANE.noise, :2, :2], self.turns)
        return arc
