"""The wheel encoders' odometry through the exact arc, and its compiled step."""

from __future__ import annotations

import numba
import numpy as np

from bots.odometry.base import ArcOdometry
from bots.odometry.layout import NODES, PLANE, SIGMAS
from bots.odometry.propagation import END_HEADING, MID_ANGLE, lay, lay_chord, node_of, propagate, wheel_terms, wheel_variances
from bots.readings import Readings
from sim.kinematics.batch import chord_of


@numba.njit(cache=True)
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


@numba.njit(cache=True, inline="always")
def sigma_arc(p: np.void, point: int, left: float, right: float) -> tuple[float, float]:
    """The arc (s, alpha) of these ticks as sigma point `point` of the encoders' calibration sees
    it: it believes the left wheel, the right wheel and the track off by one node each (`NODES`,
    its base-3 digits: `node_of`), so its wheels roll (1 + k) times the believed arc and it turns
    over (1 + k) times the believed track, exactly, however far its heading strays."""
    s_left = left * p.tick_left * (1.0 + NODES[node_of(point, 0)] * p.wheel_std)
    s_right = right * p.tick_right * (1.0 + NODES[node_of(point, 1)] * p.wheel_std)
    track = p.track * (1.0 + NODES[node_of(point, 2)] * p.track_std)
    return 0.5 * (s_left + s_right), (s_right - s_left) / track


@numba.njit(cache=True)
def sigma_encoders(p: np.void, sigmas: np.ndarray, left: float, right: float, end_heading: bool) -> None:
    """Lay these ticks on every sigma point of the encoders' calibration (`sigma_arc`), in place."""
    for i in range(SIGMAS):
        s, alpha = sigma_arc(p, i, left, right)
        lay(sigmas[i], s, alpha, end_heading)


@numba.njit(cache=True)
def sigma_encoders_both(p: np.void, mid: np.ndarray, end: np.ndarray, left: float, right: float) -> None:
    """`sigma_encoders` on the encoders' sigma points (`mid`: along the mid-angle) and the
    firmware's (`end`: along the end heading) at once: the same ticks through the same nodes, so
    each point's arc and chord are worked out once for both (the same operations: the same bits)."""
    for i in range(SIGMAS):
        s, alpha = sigma_arc(p, i, left, right)
        chord = chord_of(s, alpha)
        lay_chord(mid[i], chord, alpha, False)
        lay_chord(end[i], chord, alpha, True)


class EncoderOdometry(ArcOdometry):
    """Wheel encoders through the exact arc: ticks -> wheel arcs -> pose increment (eqs 1.3, 1.12).
    Covariance: each wheel's arc has variance (slip_var + tick_rate * tick) * |s| per step
    (first order), and the wheel scales and track are unknown by their believed size
    (`bots.uncertainty`), carried by 26 sigma points, every combination of three nodes of each
    (`ArcOdometry`, `bots.odometry.layout.SIGMAS`).

    Where the heading ends tens of degrees off (47 degrees of standard deviation at the end of a
    maze run of solve_maze) the errors lie on a curve no Gaussian describes: the points give the
    covariance of that curve (within 5 % of a 343-point rule's on drawn seed 212's path), but a
    robot far out in its belief lies well off the ellipse (seed 212's own calibration, 2.9
    standard deviations in the wheels' difference, reads NEES 50 at the end without any random
    noise) while most lie well inside it (median NEES 1.40 over 240 drawn robots, chi-square's
    2.37). The mean is carried by the rare far-out robots (the 7 of the 240 whose wheels differ by
    more than 2.4 standard deviations, 1.5 % of robots in general, carry 44 % of the 240's sum),
    so a mean over 40 strays both ways beyond the interval of 40 (2.18 to 8.02 on six sets).
    The covariance is right in expectation on every path (each of the 240 paths with 200
    calibrations drawn from the belief: mean NEES 3.00 / 3.03 / 3.13 at 10 / 50 / 100 %), and
    the robots' calibrations are the belief's given their paths; but a mean over 40 of those
    calibration-only NEES lies outside the interval of 40 in 55 % of sets at the end
    (docs/odometry.md, "Why sets of 40 stray").

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
        sigma_encoders(self.params, self.sigmas, float(left), float(right), self.end_heading)
        return encoder_step(self.params, float(self.pose[2]), self.errors, float(left), float(right), self.end_heading, self.work)
