"""One step of each default estimator's arc and error covariance, compiled, so that the Python
estimators (`bots.odometry`) and the batch of a run's robots (`bots.odometry_batch`) run the
same code: each takes a robot's parameter row (PARAMS) and returns the increment (s, alpha) for
its caller to lay down.

The fused estimator is an extended Kalman filter of the pose and the four calibration errors of
`bots.uncertainty` (wheel scales, track, mouse resolution). Each step both sensors measure the
same increment (s, alpha): u = u_enc + J_enc k + n_enc = u_mouse + J_mouse k + n_mouse. Their
difference d (each corrected by the current calibration estimate) measures the calibration
errors alone, with noise n_enc - n_mouse: the Kalman update moves the calibration (and, through
their correlation, the pose). The increment laid down is the two corrected increments weighted by
their information, whose noise is uncorrelated with d's (the same weights), so one step uses
every reading once. The Jacobians are taken at the mouse's increment (fine counts), not the
encoders' (a tick arrives on some steps only): Jacobians taken at the encoders' quantised values
correlate with their own quantisation error and bias the calibration.

Per step, a count's quantisation (up to one count) is far above the random noise, so the
weights and the update take it as white noise of variance count²/12 on each channel: this
over-states its sum over many steps (carried counts lag by less than one count, never more),
which keeps the calibration update cautious. The propagated covariance takes only the random
noise; the quantisation lag is reported beside it (`lag`, as `bots.uncertainty` does).

Two detectors leave a sensor out where its model does not hold (`bots.odometry.FusedOdometry`
says why they hold): slip (the encoders' distance strays from the mouse's beyond a quantisation
band) and wall contact (the mouse's rotation strays from the encoders', a slide read as
rotation); a channel left out gets the variance IGNORED.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from bots.uncertainty import ERRORS, LEFT_SCALE, MOUSE_SCALE, RIGHT_SCALE, TRACK_SCALE, mouse_terms, propagate, wheel_terms

IGNORED = 1e6
"""Variance (m², rad²) of a channel left out for a step: a million times any real one."""

# a robot's parameters (PARAMS,) float64: metres of rim per tick (left, right), believed track
# (m), mouse counts per metre, mouse mount x, y (m), the fused estimator's tolerance (m) and turn
# tolerance (rad), its TURN_MEMORY (s) and GATE (standard deviations), passed, not compiled in
# (numba's cache would not see them change in bots.odometry), whether the robot has the mouse estimators
# (1.0) or only the encoders' (0.0), and the believed noise (`bots.uncertainty.Belief`): relative
# slip variance, spurious-tick variance per wheel (m²), mouse reading variance (m²); and the
# fused estimator's DISTANCE_MEMORY (m)
TICK_LEFT, TICK_RIGHT, TRACK, PER_METRE, MOUNT_X, MOUNT_Y, TOLERANCE, TURN_TOLERANCE, MEMORY, GATE, HAS_MOUSE = range(11)
SLIP_VAR, TICK_VAR_LEFT, TICK_VAR_RIGHT, MOUSE_VAR, DISTANCE_MEMORY, PARAMS = range(11, 17)
# the fused estimator's detector state (STATE,) float64, as `FusedOdometry`'s attributes of those
# names; TIME is nan before the first step
DISAGREEMENT, TURN_DISAGREEMENT, TAKEN, TURNING, TIME, TRAVEL, TURN_TRAVEL, STATE = range(8)


@numba.njit(cache=True)
def _mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a @ b for 2-D arrays (numba's own needs SciPy's BLAS)."""
    out = np.zeros((a.shape[0], b.shape[1]))
    for i in range(a.shape[0]):
        for k in range(a.shape[1]):
            for j in range(b.shape[1]):
                out[i, j] += a[i, k] * b[k, j]
    return out


@numba.njit(cache=True)
def _apply(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """a @ v for a 2-D a and a 1-D v."""
    out = np.zeros(a.shape[0])
    for i in range(a.shape[0]):
        for k in range(a.shape[1]):
            out[i] += a[i, k] * v[k]
    return out


@numba.njit(cache=True)
def _inverse(m: np.ndarray) -> np.ndarray:
    det = m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]
    out = np.empty((2, 2))
    out[0, 0], out[0, 1], out[1, 0], out[1, 1] = m[1, 1] / det, -m[0, 1] / det, -m[1, 0] / det, m[0, 0] / det
    return out


@numba.njit(cache=True)
def wheel_variances(p: np.ndarray, s_left: float, s_right: float) -> tuple[float, float]:
    """The random variance (m²) of each wheel's arc over a step of these arcs (m)."""
    return p[SLIP_VAR] * s_left * s_left + p[TICK_VAR_LEFT], p[SLIP_VAR] * s_right * s_right + p[TICK_VAR_RIGHT]


@numba.njit(cache=True)
def encoder_step(p: np.ndarray, heading: float, cov: np.ndarray, left: float, right: float, end_heading: bool) -> tuple[float, float]:
    """Encoder odometry: the increment of `left`, `right` ticks; `cov` propagated from `heading`."""
    s_left, s_right = left * p[TICK_LEFT], right * p[TICK_RIGHT]
    s, alpha = 0.5 * (s_left + s_right), (s_right - s_left) / p[TRACK]
    jac, noise = np.zeros((2, ERRORS)), np.zeros((2, 2))
    var_left, var_right = wheel_variances(p, s_left, s_right)
    wheel_terms(s_left, s_right, alpha, p[TRACK], var_left, var_right, jac, noise)
    propagate(cov, heading, s, alpha, end_heading, jac, noise)
    return s, alpha


@numba.njit(cache=True)
def mouse_arc(p: np.ndarray, forward: float, lateral: float) -> tuple[float, float]:
    """The mouse's increment (seed 002 §2.1): alpha = lateral/m_x, s = forward + alpha*m_y."""
    alpha = lateral / p[PER_METRE] / p[MOUNT_X]
    return forward / p[PER_METRE] + alpha * p[MOUNT_Y], alpha


@numba.njit(cache=True)
def mouse_step(p: np.ndarray, heading: float, cov: np.ndarray, forward: float, lateral: float) -> tuple[float, float]:
    """Mouse odometry: the increment of these counts; `cov` propagated from `heading`."""
    s, alpha = mouse_arc(p, forward, lateral)
    jac, noise = np.zeros((2, ERRORS)), np.zeros((2, 2))
    mouse_terms(s, alpha, p[MOUNT_X], p[MOUNT_Y], p[MOUSE_VAR], jac, noise)
    propagate(cov, heading, s, alpha, False, jac, noise)
    return s, alpha


@numba.njit(cache=True)
def fused_step(
    p: np.ndarray, st: np.ndarray, pose: np.ndarray, calibration: np.ndarray, cov: np.ndarray, lag: np.ndarray,
    left: float, right: float, forward: float, lateral: float, time: float,
) -> tuple[float, float, bool]:
    """The fused filter's step, in place: `pose` (3,) corrected by the update (not yet advanced),
    `calibration` (ERRORS,) the estimated errors (entries 3 on), `cov` (ERRORS, ERRORS), `lag`
    (2, 2) the increment's quantisation lag, `st` (STATE,) the detectors. Returns the increment
    (s, alpha) to lay from the corrected pose and whether the mouse slid (wall contact)."""
    track = p[TRACK]
    s_left, s_right = left * p[TICK_LEFT], right * p[TICK_RIGHT]
    u_enc = np.array([0.5 * (s_left + s_right), (s_right - s_left) / track])
    u_mouse = np.array(mouse_arc(p, forward, lateral))
    # the error models, the encoders' at the arcs of the mouse's increment (see the module)
    j_enc, r_enc, q_enc = np.zeros((2, ERRORS)), np.zeros((2, 2)), np.zeros((2, 2))
    j_mouse, r_mouse, q_mouse = np.zeros((2, ERRORS)), np.zeros((2, 2)), np.zeros((2, 2))
    count = 1.0 / p[PER_METRE]
    mouse_terms(u_mouse[0], u_mouse[1], p[MOUNT_X], p[MOUNT_Y], p[MOUSE_VAR], j_mouse, r_mouse)
    mouse_terms(u_mouse[0], u_mouse[1], p[MOUNT_X], p[MOUNT_Y], count * count / 12.0, j_mouse, q_mouse)
    corrected_mouse = u_mouse + _apply(j_mouse, calibration)
    # the detectors, on the corrected increments
    at_left = corrected_mouse[0] - 0.5 * corrected_mouse[1] * track
    at_right = corrected_mouse[0] + 0.5 * corrected_mouse[1] * track
    var_left, var_right = wheel_variances(p, at_left, at_right)
    wheel_terms(at_left, at_right, corrected_mouse[1], track, var_left, var_right, j_enc, r_enc)
    wheel_terms(at_left, at_right, corrected_mouse[1], track, p[TICK_LEFT] ** 2 / 12.0, p[TICK_RIGHT] ** 2 / 12.0, j_enc, q_enc)
    corrected_enc = u_enc + _apply(j_enc, calibration)
    # slip: the encoders' distance beyond the mouse's, over the last DISTANCE_MEMORY of the mouse's path
    forget = math.exp(-abs(corrected_mouse[0]) / p[DISTANCE_MEMORY])
    st[DISAGREEMENT] = st[DISAGREEMENT] * forget + corrected_enc[0] - corrected_mouse[0]
    st[TRAVEL] = st[TRAVEL] * forget + abs(corrected_mouse[0])
    scale = math.sqrt(max(0.25 * (cov[LEFT_SCALE, LEFT_SCALE] + cov[RIGHT_SCALE, RIGHT_SCALE] + 2.0 * cov[LEFT_SCALE, RIGHT_SCALE]) + cov[MOUSE_SCALE, MOUSE_SCALE], 0.0))
    slipped = abs(st[DISAGREEMENT]) > p[TOLERANCE] + p[GATE] * scale * st[TRAVEL]
    # a slide: the mouse's rotation beyond the encoders', over the last TURN_MEMORY seconds
    if math.isnan(st[TIME]):
        keep = 1.0
    else:
        elapsed = time - st[TIME]
        keep = math.exp(-(0.0 if 0.0 > elapsed else elapsed) / p[MEMORY])
    st[TIME] = time
    st[TURNING] = st[TURNING] * keep + abs(corrected_enc[1])
    st[TURN_TRAVEL] = st[TURN_TRAVEL] * keep + abs(corrected_enc[0])
    st[TURN_DISAGREEMENT] = st[TURN_DISAGREEMENT] * keep + corrected_mouse[1] - corrected_enc[1]
    st[TAKEN] = st[TAKEN] * keep
    turn_scale = math.sqrt(max(cov[TRACK_SCALE, TRACK_SCALE] + cov[MOUSE_SCALE, MOUSE_SCALE], 0.0))
    mismatch = math.sqrt(max(cov[LEFT_SCALE, LEFT_SCALE] + cov[RIGHT_SCALE, RIGHT_SCALE] - 2.0 * cov[LEFT_SCALE, RIGHT_SCALE], 0.0))
    band = p[TURN_TOLERANCE] + p[GATE] * (turn_scale * st[TURNING] + mismatch * st[TURN_TRAVEL] / track)
    sliding = abs(st[TURN_DISAGREEMENT]) > band
    a_enc, a_mouse = r_enc + q_enc, r_mouse + q_mouse
    if slipped:
        a_enc[0, 0], a_enc[0, 1], a_enc[1, 0] = IGNORED, 0.0, 0.0
    if sliding:
        a_mouse[1, 1], a_mouse[0, 1], a_mouse[1, 0] = IGNORED, 0.0, 0.0
    # the update: d = corrected_enc - corrected_mouse = h e + v, e = truth - estimate
    h = j_mouse - j_enc
    d = corrected_enc - corrected_mouse
    noise_d = a_enc + a_mouse
    ph = _mul(cov, h.T)  # (ERRORS, 2)
    gain = _mul(ph, _inverse(_mul(h, ph) + noise_d))
    correction = _apply(gain, d)
    keep_cov = np.eye(ERRORS) - _mul(gain, h)
    cov[:, :] = _mul(_mul(keep_cov, cov), keep_cov.T) + _mul(_mul(gain, noise_d), gain.T)  # (Joseph's form: stays symmetric, positive)
    for r in range(3):
        pose[r] += correction[r]
    for r in range(3, ERRORS):
        calibration[r] += correction[r]
    # the increment: both, corrected by the updated calibration, by their information
    i_enc, i_mouse = _inverse(a_enc), _inverse(a_mouse)
    weights = _inverse(i_enc + i_mouse)
    w_enc, w_mouse = _mul(weights, i_enc), _mul(weights, i_mouse)
    u = _apply(w_enc, u_enc + _apply(j_enc, calibration)) + _apply(w_mouse, u_mouse + _apply(j_mouse, calibration))
    jac = _mul(w_enc, j_enc) + _mul(w_mouse, j_mouse)
    noise = _mul(_mul(w_enc, r_enc), w_enc.T) + _mul(_mul(w_mouse, r_mouse), w_mouse.T)
    lag[:, :] = _mul(_mul(w_enc, q_enc), w_enc.T) + _mul(_mul(w_mouse, q_mouse), w_mouse.T)
    propagate(cov, pose[2], u[0], u[1], False, jac, noise)
    s, alpha = u[0], u[1]
    if sliding:  # what the mouse's rotation added before the slide was seen is taken back
        alpha -= st[TAKEN]
        st[TAKEN] = 0.0
    else:
        st[TAKEN] += alpha - corrected_enc[1]
    return s, alpha, sliding
