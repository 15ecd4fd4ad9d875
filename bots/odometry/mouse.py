"""The optical mouse's odometry through the inverse model of seed 002, its compiled step, and the
slide watch it shares with the fused estimator."""

from __future__ import annotations

import math

import numba
import numpy as np

from bots.odometry.base import ArcOdometry
from bots.odometry.layout import ESTIMATE, MOUSE_NODES, MOUSE_SIGMAS, PLANE
from bots.odometry.propagation import MID_ANGLE, carry_noise, lay, lay_point, mouse_terms, mouse_variance, noise_of, propagate, wheel_variances
from bots.readings import Readings
from bots.uncertainty import COUNT_VARIANCE, ERROR
from sim.kinematics.batch import INNER, chord_of


@numba.njit(cache=True, error_model="numpy", **INNER)
def mouse_arc(p: np.void, forward: float, lateral: float) -> tuple[float, float]:
    """The mouse's increment (seed 002 §2.1): alpha = lateral/m_x, s = forward + alpha*m_y."""
    alpha = lateral / p.per_metre / p.mount_x
    return forward / p.per_metre + alpha * p.mount_y, alpha


@numba.njit(cache=True, error_model="numpy")
def mouse_step(p: np.void, heading: float, cov: np.ndarray, forward: float, lateral: float, work: np.ndarray) -> tuple[float, float]:
    """Mouse odometry: the increment of these counts; `cov` propagated from `heading` (`work`:
    scratch, `workspace`)."""
    s, alpha = mouse_arc(p, forward, lateral)
    jac, noise = work[PLANE.jac, :2, :], work[PLANE.noise, :2, :2]
    mouse_terms(s, alpha, p.mount_x, p.mount_y, mouse_variance(p, s, alpha), jac, noise)
    propagate(cov, heading, s, alpha, MID_ANGLE, jac, noise, work)
    return s, alpha


@numba.njit(cache=True, error_model="numpy")
def sigma_mouse(p: np.void, sigmas: np.ndarray, noises: np.ndarray, forward: float, lateral: float, noise: np.ndarray, turns: np.ndarray) -> None:
    """Lay these counts on the sigma points of the mouse's resolution (`MOUSE_NODES` standard
    deviations off the estimate's: a finer mouse counts (1 + k) times the floor), each
    point's random part `noises` (COVARIANCE_FIELDS, SIGMAS; the first MOUSE_SIGMAS used) carried
    with the step's `noise` (2, 2; `mouse_terms`) along its own path, in place (`lay_point`,
    `carry_noise`; `turns` (3, SIGMAS): scratch)."""
    s, alpha = mouse_arc(p, forward, lateral)
    for i in range(MOUSE_SIGMAS):
        scale = 1.0 + MOUSE_NODES[i] * p.mouse_scale_std
        lay_point(sigmas, turns, i, s / scale, chord_of(s / scale, alpha / scale), alpha / scale, MID_ANGLE)
    carry_noise(noises[:, :MOUSE_SIGMAS], turns[:, :MOUSE_SIGMAS], MID_ANGLE, noise_of(noise))


@numba.njit(cache=True, error_model="numpy")
def watch_slides(p: np.void, watch: np.void, disagreement: float, var: float, turned: float, travelled: float, time: float) -> tuple[float, float]:
    """What a slide may have done to the heading: two variances (rad²) its caller may add to it
    this step (the slide's size, `size`, or the uncertainty of its measure, `measure`), and the
    watch's slide hypothesis turned back, in place. A robot sliding
    along a wall moves its mouse sideways, which the mouse reads as rotation, while the encoders
    turn as the wheels do: the mouse's rotation beyond the encoders' (`disagreement`, rad, this
    step), summed with a memory of SLIDE_MEMORY seconds, stays within the quantisation band
    (`TURN_TOLERANCE`), GATE standard deviations of its random noise (`var`, rad² this step,
    summed as it is) and SLIDE_GATE believed calibration errors of the recent net turning and
    driving (`turned` rad, signed, `travelled` m this step: a scale error's disagreement follows
    the net turn, the quantisation's ticks back and forth cancel) unless the robot slid. Beyond
    it the whole sum is what the slide may have turned the mouse's heading by: while it grows,
    `size` grows with its square (an episode adds its peak squared; the watch starts again once
    the sum is back within the band). Slower slides than about the band over SLIDE_MEMORY go
    unseen.

    The hypothesis (`watch.hypothesis`, a pose its caller lays every increment on, as on the
    estimate) is where the estimate would be had every such turn been a slide: while beyond the
    band, each step's disagreement, and at the first such step the sum not yet taken (`pending`,
    summed with the same memory while within the band), is turned back there, once each. Its
    offset from the estimate (`HYPOTHESIS_WEIGHT`) is what the slides may have done to the
    heading and, however far the path bends after, to the position: the heading's variance alone
    would spread the position across the path only (first order), and a heading a quarter turn
    off moves it along the path as much. The hypothesis is only as good as the slide's measure:
    the sum also holds the encoders' turn error over it, so at an episode's first step `measure`
    is that error's variance (the sum's random variance, one believed calibration error of the
    net turning and driving, and both sensors' quantisation since the sum started). An estimate
    that adds the hypothesis's offset adds `measure`; adding `size` as well counts the slide twice."""
    last = watch.time
    keep = 1.0 if math.isnan(last) else math.exp(-max(time - last, 0.0) / p.slide_memory)
    watch.time = time
    watch.disagreement = watch.disagreement * keep + disagreement
    watch.turning = watch.turning * keep + turned
    watch.travel = watch.travel * keep + abs(travelled)
    watch.var = watch.var * keep * keep + var
    turn_scale = math.sqrt(p.track_std * p.track_std + p.mouse_scale_std * p.mouse_scale_std)
    band = p.turn_tolerance + p.gate * math.sqrt(watch.var) + p.slide_gate * (turn_scale * abs(watch.turning) + math.sqrt(2.0) * p.wheel_std * watch.travel / p.track)
    pending = watch.pending * keep + disagreement
    level, peak = abs(watch.disagreement), watch.peak
    if level <= band:
        watch.peak, watch.pending = 0.0, pending
        return 0.0, 0.0
    watch.peak, watch.pending = max(level, peak), 0.0
    watch.hypothesis[2] -= pending
    size = max(level * level - peak * peak, 0.0)
    if peak > 0.0:
        return size, 0.0
    calibration = turn_scale * abs(watch.turning) + math.sqrt(2.0) * p.wheel_std * watch.travel / p.track
    count = 1.0 / p.per_metre
    quantisation = COUNT_VARIANCE * ((p.tick_left * p.tick_left + p.tick_right * p.tick_right) / (p.track * p.track) + count * count / (p.mount_x * p.mount_x))
    return size, watch.var + calibration * calibration + quantisation


@numba.njit(cache=True, error_model="numpy")
def turn_check(p: np.void, left: float, right: float, s: float, alpha: float) -> tuple[float, float, float]:
    """What the mouse estimate's slide watch compares (`watch_slides`): the encoders' increment
    (s m, alpha rad) of these ticks by the believed geometry, and the random variance (rad²) of
    the difference of the two rotations, the mouse's increment being (s, alpha)."""
    s_left, s_right = left * p.tick_left, right * p.tick_right
    var_left, var_right = wheel_variances(p, s_left, s_right)
    var = (var_left + var_right) / (p.track * p.track) + mouse_variance(p, s, alpha) / (p.mount_x * p.mount_x)
    return 0.5 * (s_left + s_right), (s_right - s_left) / p.track, var


class MouseOdometry(ArcOdometry):
    """The optical mouse through the inverse model (seed 002 §2.1): alpha = lateral/m_x,
    s = forward + alpha*m_y, at the dpi the robot believes (the nominal one). Covariance: each
    axis's reading has the mouse's count variance per step, and the resolution is unknown by its
    believed size (`bots.uncertainty`). Not modelled: a mouse too fast to track (reads zero).

    The resolution's error is carried by six sigma points (`ArcOdometry`, `bots.odometry.layout.MOUSE_NODES`:
    three span only a plane where five laps of turning bend the pose's error out of it), and the random
    part along each point's path as well; a slide along a wall,
    which the mouse reads as rotation, by the slide watch (`watch_slides`, which looks at the
    encoders' ticks only for the covariance, never to move the estimate): it turns back a
    hypothesis dead-reckoned beside the estimate, whose offset the covariance adds, so that a
    slide of a quarter turn or more moves the position's uncertainty along the path as well as
    across it, and widens the heading's variance by how uncertain the slide's measure is (its
    `measure`; widened by the slide's size as well, a slide counted twice, the maze's mean NEES
    over 120 drawn robots ended at 2.48, too cautious, and with the hypothesis alone at 3.59,
    over-confident; docs/odometry.md has the maze's NEES)."""

    name = "mouse"
    uses_mouse = True
    watch = ESTIMATE.mouse
    caveat = ("a slide along a wall turns its heading, by more than a half turn in some runs: no Gaussian covers a heading "
              "that wraps, and a slide slower than its slide watch sees is not in its covariance")  # fmt: skip
    sigma_count = MOUSE_SIGMAS

    def __init__(self) -> None:
        super().__init__()

    def step(self, readings: Readings) -> tuple[float, float]:
        forward, lateral = readings.mouse_counts.tolist()
        left, right = readings.encoder_ticks.tolist()
        s, alpha = mouse_step(self.params, float(self.pose[2]), self.errors, float(forward), float(lateral), self.work)
        sigma_mouse(self.params, self.sigmas, self.noises, float(forward), float(lateral), self.work[PLANE.noise, :2, :2], self.turns)
        s_enc, alpha_enc, var = turn_check(self.params, float(left), float(right), s, alpha)
        watch = self.state["mouse_watch"]
        lay(watch["hypothesis"], s, alpha, False)
        self.errors[ERROR.heading, ERROR.heading] += watch_slides(self.params, watch, alpha - alpha_enc, var, alpha_enc, s_enc, float(readings.time))[1]
        return s, alpha
