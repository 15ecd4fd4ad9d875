"""One step of each default estimator's arc and error covariance, compiled, so that the Python
estimators (`bots.odometry.base` and its subclasses) and the batch of a run's robots (`bots.odometry.batch`) run the
same code: each takes a robot's parameter row (PARAMS) and returns the increment (s, alpha) for
its caller to lay down; `batch_step` steps every robot of the batch. Every compiled part of the
odometry is in this one file: numba caches a kernel by its own file's stamp, so a kernel calling
one from another file would keep the old callee after that file changed.

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

Two detectors leave a sensor out where its model does not hold (`bots.odometry.fused.FusedOdometry`
says why they hold): slip (the encoders' distance strays from the mouse's beyond a quantisation
band) and wall contact (the mouse's rotation strays from the encoders', a slide read as
rotation); a channel left out gets the variance IGNORED.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from bots.uncertainty import (
    ERRORS,
    HEADING,
    LEFT_SCALE,
    MOUSE_SCALE,
    RIGHT_SCALE,
    TRACK_SCALE,
)
from sim.kinematics.batch import advance_one

# the estimates of one robot in the batch (n, ESTIMATES, 3): the order of `default_estimators`
ENCODERS, FIRMWARE, MOUSE, FUSED, ESTIMATES = 0, 1, 2, 3, 4
IGNORED = 1e6
MID_ANGLE, END_HEADING = 0.5, 1.0
"""Where an arc's chord is laid (`propagate`'s share of the heading change): along the mid-angle
(exact, seed 002 eqs 1.7, 1.12) or along the end heading (the c't-Bot firmware)."""
PROPAGATE_WORK = 3
"""Scratch planes (`workspace`) `propagate` uses; the steps that call it use those after."""
WORK = 29
"""Scratch planes of (ERRORS, ERRORS) a step uses at most (`fused_step`)."""
"""Variance (m², rad²) of a channel left out for a step: a million times any real one."""

# a robot's parameters (PARAMS,) float64: metres of rim per tick (left, right), believed track
# (m), mouse counts per metre, mouse mount x, y (m), the fused estimator's tolerance (m) and turn
# tolerance (rad), its TURN_MEMORY (s) and GATE (standard deviations), passed, not compiled in
# (numba's cache would not see them change in bots.odometry), whether the robot has the mouse estimators
# (1.0) or only the encoders' (0.0), and the believed noise (`bots.uncertainty.Belief`): relative
# slip variance, spurious-tick variance per wheel (m²), mouse reading variance (m²); and the
# fused estimator's DISTANCE_MEMORY (m)
TICK_LEFT, TICK_RIGHT, TRACK, PER_METRE, MOUNT_X, MOUNT_Y, TOLERANCE, TURN_TOLERANCE, MEMORY, GATE, HAS_MOUSE = range(11)
SLIP_VAR, TICK_VAR_LEFT, TICK_VAR_RIGHT, MOUSE_VAR, DISTANCE_MEMORY = range(11, 16)
# and the believed standard deviations of the calibration errors (`bots.uncertainty.Belief`:
# each wheel's scale, the track's, the mouse resolution's), the sigma points' offsets
WHEEL_STD, TRACK_STD, MOUSE_SCALE_STD = range(16, 19)
# and the slide watch's memory (s) and gate (standard deviations of the calibration), `watch_slides`
SLIDE_MEMORY, SLIDE_GATE, PARAMS = range(19, 22)
# the fused estimator's detector state (STATE,) float64, as `FusedOdometry`'s attributes of those
# names; TIME is nan before the first step
DISAGREEMENT, TURN_DISAGREEMENT, TAKEN, TURNING, TIME, TRAVEL, TURN_TRAVEL, DISAGREEMENT_VAR, TURN_VAR = range(9)
SIGMAS = 6
"""Sigma points of a dead-reckoning estimator (`sigma_poses`): two per calibration error it has
(encoders: left wheel, right wheel, track; mouse: resolution, its other four unused)."""
SIGMA_POSES = 9
"""Where a robot's state row holds the sigma points' poses (SIGMAS, 3) of its encoders, firmware
and mouse estimates, one block after another (`sigma_block`)."""
SLIDE_STATE = SIGMA_POSES + 3 * SIGMAS * 3
"""Where the state row holds the slide watch (`watch_slides`) of the mouse estimate, then the fused one's."""
SLIDE_DISAGREEMENT, SLIDE_TURNING, SLIDE_TRAVEL, SLIDE_PEAK, SLIDE_TIME, SLIDE_VAR, SLIDES = range(7)
STATE = SLIDE_STATE + 2 * SLIDES
SIGMA_SPREAD = math.sqrt(3.0)
"""Standard deviations from the estimate to each sigma point: sqrt(n + kappa) with n + kappa = 3,
Julier and Uhlmann's choice for Gaussian errors; each point then weighs 1 / (2 * 3)."""


@numba.njit(cache=True)
def wheel_terms(s_left: float, s_right: float, alpha: float, track: float, var_left: float, var_right: float,
                jac: np.ndarray, noise: np.ndarray) -> None:  # fmt: skip
    """The encoder increment's error model, in place: `jac` (2, ERRORS) of (s, alpha) on the
    scales for wheel arcs s_left, s_right (m) and heading change alpha over `track` (m); `noise`
    (2, 2) for independent wheel-arc variances var_left, var_right (m²)."""
    jac[:, :] = 0.0
    jac[0, LEFT_SCALE], jac[0, RIGHT_SCALE] = 0.5 * s_left, 0.5 * s_right
    jac[1, LEFT_SCALE], jac[1, RIGHT_SCALE], jac[1, TRACK_SCALE] = -s_left / track, s_right / track, -alpha
    noise[0, 0] = 0.25 * (var_left + var_right)
    noise[0, 1] = noise[1, 0] = 0.5 * (var_right - var_left) / track
    noise[1, 1] = (var_left + var_right) / (track * track)


@numba.njit(cache=True)
def mouse_terms(s: float, alpha: float, mount_x: float, mount_y: float, var: float, jac: np.ndarray, noise: np.ndarray) -> None:
    """The mouse increment's error model, in place: `jac` on the resolution's error for the
    increment (s m, alpha rad), `noise` for a variance `var` (m²) of each axis's reading, through
    alpha = lateral/m_x, s = forward + alpha*m_y."""
    jac[:, :] = 0.0
    jac[0, MOUSE_SCALE], jac[1, MOUSE_SCALE] = -s, -alpha
    lever = mount_y / mount_x
    noise[0, 0] = var * (1.0 + lever * lever)
    noise[0, 1] = noise[1, 0] = var * lever / mount_x
    noise[1, 1] = var / (mount_x * mount_x)


@numba.njit(cache=True)
def propagate(cov: np.ndarray, heading: float, s: float, alpha: float, share: float, jac: np.ndarray, noise: np.ndarray,
              work: np.ndarray) -> None:  # fmt: skip
    """`cov` (ERRORS, ERRORS) after laying the increment (s, alpha) from `heading` (rad, before
    the step) along `heading + share * alpha` (`MID_ANGLE`, exact, or `END_HEADING`, the
    firmware), whose error is jac @ errors + n, n ~ noise: cov <- A cov A^T + G noise G^T, with A
    the identity but for the pose rows (d pose'/d pose and G @ jac, G = d pose'/d (s, alpha)).
    `work` (WORK, ERRORS, ERRORS): scratch planes (`workspace`), its first PROPAGATE_WORK used.
    (A float, not a bool: numba compiles a function once for each constant bool it is called with.)"""
    angle = heading + share * alpha
    c, sn = math.cos(angle), math.sin(angle)
    lever = share * s
    g = ((c, -lever * sn), (sn, lever * c), (0.0, 1.0))
    a, rows, pose = work[0, :3], work[1, :3], work[2, :3, :3]  # rows: a @ cov; pose: a @ cov @ a^T, + G noise G^T
    a[:, :] = 0.0
    for r in range(3):
        a[r, r] = 1.0
        for j in range(ERRORS):
            a[r, j] += g[r][0] * jac[0, j] + g[r][1] * jac[1, j]
    a[0, HEADING] -= s * sn
    a[1, HEADING] += s * c
    for r in range(3):
        for j in range(ERRORS):
            total = 0.0
            for k in range(ERRORS):
                total += a[r, k] * cov[k, j]
            rows[r, j] = total
    for r in range(3):
        for q in range(3):
            total = 0.0
            for k in range(ERRORS):
                total += rows[r, k] * a[q, k]
            pose[r, q] = total + (g[r][0] * (noise[0, 0] * g[q][0] + noise[0, 1] * g[q][1]) + g[r][1] * (noise[1, 0] * g[q][0] + noise[1, 1] * g[q][1]))
    for r in range(3):
        for j in range(3, ERRORS):
            cov[r, j] = cov[j, r] = rows[r, j]
        for q in range(3):
            cov[r, q] = pose[r, q]


@numba.njit(cache=True)
def pose_covariance(cov: np.ndarray, heading: float, lag: np.ndarray, out: np.ndarray) -> None:
    """The reported pose covariance's six entries (COVARIANCE_FIELDS) into `out`: the propagated
    one plus the quantisation lag `lag` (2, 2) of the increment (s along the heading, alpha)."""
    c, sn = math.cos(heading), math.sin(heading)
    out[0] = cov[0, 0] + lag[0, 0] * c * c
    out[1] = cov[0, 1] + lag[0, 0] * c * sn
    out[2] = cov[0, 2] + lag[0, 1] * c
    out[3] = cov[1, 1] + lag[0, 0] * sn * sn
    out[4] = cov[1, 2] + lag[0, 1] * sn
    out[5] = cov[2, 2] + lag[1, 1]


def workspace() -> np.ndarray:
    """Scratch for the steps (WORK planes of (ERRORS, ERRORS)): their intermediates live there,
    not in arrays allocated every step (which cost more than the arithmetic)."""
    return np.zeros((WORK, ERRORS, ERRORS))


def fresh_state() -> np.ndarray:
    """A robot's state row (STATE,) before its first step: no time seen yet (nan), all else zero
    (the sigma points are set to the start pose by their estimators)."""
    state = np.zeros(STATE)
    state[TIME] = state[SLIDE_STATE + SLIDE_TIME] = state[SLIDE_STATE + SLIDES + SLIDE_TIME] = math.nan
    return state


@numba.njit(cache=True)
def _mul(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> np.ndarray:
    """out <- a @ b for 2-D arrays (numba's own needs SciPy's BLAS); `out` (a view of scratch)."""
    out[:, :] = 0.0
    for i in range(a.shape[0]):
        for k in range(a.shape[1]):
            for j in range(b.shape[1]):
                out[i, j] += a[i, k] * b[k, j]
    return out


@numba.njit(cache=True)
def _apply(a: np.ndarray, v: np.ndarray, out: np.ndarray) -> np.ndarray:
    """out <- a @ v for a 2-D a and a 1-D v."""
    out[:] = 0.0
    for i in range(a.shape[0]):
        for k in range(a.shape[1]):
            out[i] += a[i, k] * v[k]
    return out


@numba.njit(cache=True)
def _inverse(m: np.ndarray, out: np.ndarray) -> np.ndarray:
    """out <- the inverse of the 2 x 2 `m`."""
    det = m[0, 0] * m[1, 1] - m[0, 1] * m[1, 0]
    out[0, 0], out[0, 1], out[1, 0], out[1, 1] = m[1, 1] / det, -m[0, 1] / det, -m[1, 0] / det, m[0, 0] / det
    return out


@numba.njit(cache=True)
def _add(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> np.ndarray:
    """out <- a + b, element by element (2-D)."""
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            out[i, j] = a[i, j] + b[i, j]
    return out


@numba.njit(cache=True)
def wheel_variances(p: np.ndarray, s_left: float, s_right: float) -> tuple[float, float]:
    """The random variance (m²) of each wheel's arc over a step of these arcs (m): slip and
    spurious ticks both grow with the distance rolled (m² per metre each), whatever the step."""
    return (p[SLIP_VAR] + p[TICK_VAR_LEFT]) * abs(s_left), (p[SLIP_VAR] + p[TICK_VAR_RIGHT]) * abs(s_right)


@numba.njit(cache=True)
def mouse_variance(p: np.ndarray, s: float, alpha: float) -> float:
    """The random variance (m²) of each mouse axis over a step of this increment: its noise
    (m² per metre) times the floor the sensor passed, (s - alpha m_y, alpha m_x)."""
    return p[MOUSE_VAR] * math.hypot(s - alpha * p[MOUNT_Y], alpha * p[MOUNT_X])


@numba.njit(cache=True)
def encoder_step(p: np.ndarray, heading: float, cov: np.ndarray, left: float, right: float, end_heading: bool, work: np.ndarray) -> tuple[float, float]:
    """Encoder odometry: the increment of `left`, `right` ticks; `cov` propagated from `heading`
    (`work`: scratch, `workspace`)."""
    s_left, s_right = left * p[TICK_LEFT], right * p[TICK_RIGHT]
    s, alpha = 0.5 * (s_left + s_right), (s_right - s_left) / p[TRACK]
    jac, noise = work[PROPAGATE_WORK, :2, :], work[PROPAGATE_WORK + 1, :2, :2]
    var_left, var_right = wheel_variances(p, s_left, s_right)
    wheel_terms(s_left, s_right, alpha, p[TRACK], var_left, var_right, jac, noise)
    propagate(cov, heading, s, alpha, END_HEADING if end_heading else MID_ANGLE, jac, noise, work)
    return s, alpha


@numba.njit(cache=True)
def mouse_arc(p: np.ndarray, forward: float, lateral: float) -> tuple[float, float]:
    """The mouse's increment (seed 002 §2.1): alpha = lateral/m_x, s = forward + alpha*m_y."""
    alpha = lateral / p[PER_METRE] / p[MOUNT_X]
    return forward / p[PER_METRE] + alpha * p[MOUNT_Y], alpha


@numba.njit(cache=True)
def mouse_step(p: np.ndarray, heading: float, cov: np.ndarray, forward: float, lateral: float, work: np.ndarray) -> tuple[float, float]:
    """Mouse odometry: the increment of these counts; `cov` propagated from `heading` (`work`:
    scratch, `workspace`)."""
    s, alpha = mouse_arc(p, forward, lateral)
    jac, noise = work[PROPAGATE_WORK, :2, :], work[PROPAGATE_WORK + 1, :2, :2]
    mouse_terms(s, alpha, p[MOUNT_X], p[MOUNT_Y], mouse_variance(p, s, alpha), jac, noise)
    propagate(cov, heading, s, alpha, MID_ANGLE, jac, noise, work)
    return s, alpha


@numba.njit(cache=True)
def sigma_block(state: np.ndarray, estimate: int) -> np.ndarray:
    """The (SIGMAS, 3) sigma-point poses of estimate ENCODERS, FIRMWARE or MOUSE in a robot's state row (a view)."""
    start = SIGMA_POSES + estimate * SIGMAS * 3
    return state[start : start + SIGMAS * 3].reshape((SIGMAS, 3))


@numba.njit(cache=True)
def sigma_encoders(p: np.ndarray, sigmas: np.ndarray, left: float, right: float, end_heading: bool) -> None:
    """Lay these ticks on every sigma point of the encoders' calibration, in place: point 2j
    (2j + 1) believes error j (left wheel, right wheel, track) SIGMA_SPREAD standard deviations
    above (below) the estimate, so its wheels roll (1 + k) times the believed arc and it turns
    over (1 + k) times the believed track, exactly, however far its heading strays."""
    for i in range(SIGMAS):
        offset = (SIGMA_SPREAD if i % 2 == 0 else -SIGMA_SPREAD) * (p[WHEEL_STD] if i < 4 else p[TRACK_STD])
        s_left = left * p[TICK_LEFT] * (1.0 + (offset if i // 2 == 0 else 0.0))
        s_right = right * p[TICK_RIGHT] * (1.0 + (offset if i // 2 == 1 else 0.0))
        track = p[TRACK] * (1.0 + (offset if i // 2 == 2 else 0.0))
        _lay(sigmas[i], 0.5 * (s_left + s_right), (s_right - s_left) / track, end_heading)


@numba.njit(cache=True)
def sigma_mouse(p: np.ndarray, sigmas: np.ndarray, forward: float, lateral: float) -> None:
    """Lay these counts on the two sigma points of the mouse's resolution (SIGMA_SPREAD standard
    deviations above and below the estimate: a finer mouse counts (1 + k) times the floor)."""
    s, alpha = mouse_arc(p, forward, lateral)
    for i in range(2):
        scale = 1.0 + (SIGMA_SPREAD if i == 0 else -SIGMA_SPREAD) * p[MOUSE_SCALE_STD]
        _lay(sigmas[i], s / scale, alpha / scale, False)


@numba.njit(cache=True)
def add_spread(sigmas: np.ndarray, count: int, pose: np.ndarray, out: np.ndarray) -> None:
    """Add the spread of the first `count` sigma points about `pose` to the covariance entries
    `out` (COVARIANCE_FIELDS): the calibration's part of the error, unscented (each point weighs
    1 / (2 SIGMA_SPREAD²), the estimate itself the rest)."""
    weight = 0.5 / (SIGMA_SPREAD * SIGMA_SPREAD)
    for i in range(count):
        dx, dy, dt = sigmas[i, 0] - pose[0], sigmas[i, 1] - pose[1], sigmas[i, 2] - pose[2]
        out[0] += weight * dx * dx
        out[1] += weight * dx * dy
        out[2] += weight * dx * dt
        out[3] += weight * dy * dy
        out[4] += weight * dy * dt
        out[5] += weight * dt * dt


@numba.njit(cache=True)
def slide_block(state: np.ndarray, estimate: int) -> np.ndarray:
    """The (SLIDES,) slide watch of estimate MOUSE or FUSED in a robot's state row (a view)."""
    start = SLIDE_STATE + (0 if estimate == MOUSE else SLIDES)
    return state[start : start + SLIDES]


@numba.njit(cache=True)
def watch_slides(p: np.ndarray, watch: np.ndarray, cov: np.ndarray, disagreement: float, var: float, turned: float, travelled: float,
                 time: float) -> None:  # fmt: skip
    """Widen the heading's variance by what a slide may have added, in place. A robot sliding
    along a wall moves its mouse sideways, which the mouse reads as rotation, while the encoders
    turn as the wheels do: the mouse's rotation beyond the encoders' (`disagreement`, rad, this
    step), summed with a memory of SLIDE_MEMORY seconds, stays within the quantisation band
    (`TURN_TOLERANCE`), GATE standard deviations of its random noise (`var`, rad² this step,
    summed as it is) and SLIDE_GATE believed calibration errors of the recent net turning and
    driving (`turned` rad, signed, `travelled` m this step: a scale error's disagreement follows
    the net turn, the quantisation's ticks back and forth cancel) unless the robot slid. Beyond
    it the whole sum is what the slide may have turned the mouse's heading by: while it grows,
    the variance grows with its square (an episode adds its peak squared; the watch starts again
    once the sum is back within the band). Slower slides than about the band over SLIDE_MEMORY
    go unseen."""
    last = watch[SLIDE_TIME]
    keep = 1.0 if math.isnan(last) else math.exp(-max(time - last, 0.0) / p[SLIDE_MEMORY])
    watch[SLIDE_TIME] = time
    watch[SLIDE_DISAGREEMENT] = watch[SLIDE_DISAGREEMENT] * keep + disagreement
    watch[SLIDE_TURNING] = watch[SLIDE_TURNING] * keep + turned
    watch[SLIDE_TRAVEL] = watch[SLIDE_TRAVEL] * keep + abs(travelled)
    watch[SLIDE_VAR] = watch[SLIDE_VAR] * keep * keep + var
    turn_scale = math.sqrt(p[TRACK_STD] * p[TRACK_STD] + p[MOUSE_SCALE_STD] * p[MOUSE_SCALE_STD])
    band = p[TURN_TOLERANCE] + p[GATE] * math.sqrt(watch[SLIDE_VAR]) + p[SLIDE_GATE] * (turn_scale * abs(watch[SLIDE_TURNING]) + math.sqrt(2.0) * p[WHEEL_STD] * watch[SLIDE_TRAVEL] / p[TRACK])
    level = abs(watch[SLIDE_DISAGREEMENT])
    if level <= band:
        watch[SLIDE_PEAK] = 0.0
    elif level > watch[SLIDE_PEAK]:
        cov[HEADING, HEADING] += level * level - watch[SLIDE_PEAK] * watch[SLIDE_PEAK]
        watch[SLIDE_PEAK] = level


@numba.njit(cache=True)
def turn_check(p: np.ndarray, left: float, right: float, s: float, alpha: float) -> tuple[float, float, float]:
    """What the mouse estimate's slide watch compares (`watch_slides`): the encoders' increment
    (s m, alpha rad) of these ticks by the believed geometry, and the random variance (rad²) of
    the difference of the two rotations, the mouse's increment being (s, alpha)."""
    s_left, s_right = left * p[TICK_LEFT], right * p[TICK_RIGHT]
    var_left, var_right = wheel_variances(p, s_left, s_right)
    var = (var_left + var_right) / (p[TRACK] * p[TRACK]) + mouse_variance(p, s, alpha) / (p[MOUNT_X] * p[MOUNT_X])
    return 0.5 * (s_left + s_right), (s_right - s_left) / p[TRACK], var


@numba.njit(cache=True)
def _weighed(w_enc: np.ndarray, m_enc: np.ndarray, w_mouse: np.ndarray, m_mouse: np.ndarray, out: np.ndarray, work: np.ndarray) -> None:
    """out <- w_enc m_enc w_enc^T + w_mouse m_mouse w_mouse^T (2 x 2; `work`: four scratch planes)."""
    _add(_mul(_mul(w_enc, m_enc, work[0, :2, :2]), w_enc.T, work[1, :2, :2]), _mul(_mul(w_mouse, m_mouse, work[2, :2, :2]), w_mouse.T, work[3, :2, :2]), out)


@numba.njit(cache=True)
def fused_step(
    p: np.ndarray, st: np.ndarray, pose: np.ndarray, calibration: np.ndarray, cov: np.ndarray, lag: np.ndarray,
    left: float, right: float, forward: float, lateral: float, time: float, work: np.ndarray,
) -> tuple[float, float, bool]:
    """The fused filter's step, in place: `pose` (3,) corrected by the update (not yet advanced),
    `calibration` (ERRORS,) the estimated errors (entries 3 on), `cov` (ERRORS, ERRORS), `lag`
    (2, 2) the increment's quantisation lag, `st` (STATE,) the detectors; every intermediate in
    `work` (`workspace`: no allocation a step). Returns the increment (s, alpha) to lay from the
    corrected pose and whether the mouse slid (wall contact)."""
    vectors = work[PROPAGATE_WORK]  # rows: the increments and their corrections
    u_enc, u_mouse, corrected_enc, corrected_mouse, d, u = vectors[0, :2], vectors[1, :2], vectors[2, :2], vectors[3, :2], vectors[4, :2], vectors[5, :2]
    applied, correction, updated_enc, updated_mouse = vectors[6, :2], work[PROPAGATE_WORK + 1, 0], work[PROPAGATE_WORK + 1, 1, :2], work[PROPAGATE_WORK + 1, 2, :2]
    j_enc, r_enc, q_enc, a_enc = work[5, :2, :], work[6, :2, :2], work[7, :2, :2], work[8, :2, :2]
    j_mouse, r_mouse, q_mouse, a_mouse = work[9, :2, :], work[10, :2, :2], work[11, :2, :2], work[12, :2, :2]
    h, noise_d, ph, gain, keep_cov = work[13, :2, :], work[14, :2, :2], work[15, :, :2], work[16, :, :2], work[17, :, :]
    i_enc, i_mouse, weights, w_enc, w_mouse = work[18, :2, :2], work[19, :2, :2], work[20, :2, :2], work[21, :2, :2], work[22, :2, :2]
    jac, noise, scratch = work[23, :2, :], work[24, :2, :2], work[25:]
    matrix = cov[:, :]  # (every matrix a view of one type, 'A': one compile of each helper, not one per layout)
    track = p[TRACK]
    s_left, s_right = left * p[TICK_LEFT], right * p[TICK_RIGHT]
    u_enc[0], u_enc[1] = 0.5 * (s_left + s_right), (s_right - s_left) / track
    u_mouse[0], u_mouse[1] = mouse_arc(p, forward, lateral)
    # the error models, the encoders' at the arcs of the mouse's increment (see the module)
    count = 1.0 / p[PER_METRE]
    mouse_terms(u_mouse[0], u_mouse[1], p[MOUNT_X], p[MOUNT_Y], mouse_variance(p, u_mouse[0], u_mouse[1]), j_mouse, r_mouse)
    mouse_terms(u_mouse[0], u_mouse[1], p[MOUNT_X], p[MOUNT_Y], count * count / 12.0, j_mouse, q_mouse)
    _apply(j_mouse, calibration, applied)
    for k in range(2):
        corrected_mouse[k] = u_mouse[k] + applied[k]
    # the detectors, on the corrected increments
    at_left = corrected_mouse[0] - 0.5 * corrected_mouse[1] * track
    at_right = corrected_mouse[0] + 0.5 * corrected_mouse[1] * track
    var_left, var_right = wheel_variances(p, at_left, at_right)
    wheel_terms(at_left, at_right, corrected_mouse[1], track, var_left, var_right, j_enc, r_enc)
    wheel_terms(at_left, at_right, corrected_mouse[1], track, p[TICK_LEFT] ** 2 / 12.0, p[TICK_RIGHT] ** 2 / 12.0, j_enc, q_enc)
    _apply(j_enc, calibration, applied)
    for k in range(2):
        corrected_enc[k] = u_enc[k] + applied[k]
    # slip: the encoders' distance beyond the mouse's, over the last DISTANCE_MEMORY of the mouse's
    # path, against its quantisation band, GATE sigmas of its random noise summed as it is, and of
    # the calibration still unknown over that path
    forget = math.exp(-abs(corrected_mouse[0]) / p[DISTANCE_MEMORY])
    st[DISAGREEMENT] = st[DISAGREEMENT] * forget + corrected_enc[0] - corrected_mouse[0]
    st[DISAGREEMENT_VAR] = st[DISAGREEMENT_VAR] * forget * forget + r_enc[0, 0] + r_mouse[0, 0]
    st[TRAVEL] = st[TRAVEL] * forget + abs(corrected_mouse[0])
    scale = math.sqrt(max(0.25 * (cov[LEFT_SCALE, LEFT_SCALE] + cov[RIGHT_SCALE, RIGHT_SCALE] + 2.0 * cov[LEFT_SCALE, RIGHT_SCALE]) + cov[MOUSE_SCALE, MOUSE_SCALE], 0.0))
    slipped = abs(st[DISAGREEMENT]) > p[TOLERANCE] + p[GATE] * (math.sqrt(st[DISAGREEMENT_VAR]) + scale * st[TRAVEL])
    # a slide: the mouse's rotation beyond the encoders', over the last TURN_MEMORY seconds, the same way
    if math.isnan(st[TIME]):
        keep = 1.0
    else:
        elapsed = time - st[TIME]
        keep = math.exp(-(0.0 if 0.0 > elapsed else elapsed) / p[MEMORY])
    st[TIME] = time
    st[TURNING] = st[TURNING] * keep + abs(corrected_enc[1])
    st[TURN_TRAVEL] = st[TURN_TRAVEL] * keep + abs(corrected_enc[0])
    st[TURN_DISAGREEMENT] = st[TURN_DISAGREEMENT] * keep + corrected_mouse[1] - corrected_enc[1]
    st[TURN_VAR] = st[TURN_VAR] * keep * keep + r_enc[1, 1] + r_mouse[1, 1]
    st[TAKEN] = st[TAKEN] * keep
    turn_scale = math.sqrt(max(cov[TRACK_SCALE, TRACK_SCALE] + cov[MOUSE_SCALE, MOUSE_SCALE], 0.0))
    mismatch = math.sqrt(max(cov[LEFT_SCALE, LEFT_SCALE] + cov[RIGHT_SCALE, RIGHT_SCALE] - 2.0 * cov[LEFT_SCALE, RIGHT_SCALE], 0.0))
    band = p[TURN_TOLERANCE] + p[GATE] * (math.sqrt(st[TURN_VAR]) + turn_scale * st[TURNING] + mismatch * st[TURN_TRAVEL] / track)
    sliding = abs(st[TURN_DISAGREEMENT]) > band
    watch_slides(p, slide_block(st, FUSED), cov, corrected_mouse[1] - corrected_enc[1], r_enc[1, 1] + r_mouse[1, 1], corrected_enc[1], corrected_enc[0], time)
    _add(r_enc, q_enc, a_enc)
    _add(r_mouse, q_mouse, a_mouse)
    if slipped:
        a_enc[0, 0], a_enc[0, 1], a_enc[1, 0] = IGNORED, 0.0, 0.0
    if sliding:
        a_mouse[1, 1], a_mouse[0, 1], a_mouse[1, 0] = IGNORED, 0.0, 0.0
    # the update: d = corrected_enc - corrected_mouse = h e + v, e = truth - estimate
    for r in range(2):
        d[r] = corrected_enc[r] - corrected_mouse[r]
        for j in range(ERRORS):
            h[r, j] = j_mouse[r, j] - j_enc[r, j]
    _add(a_enc, a_mouse, noise_d)
    _mul(matrix, h.T, ph)  # (ERRORS, 2)
    _mul(ph, _inverse(_add(_mul(h, ph, scratch[0, :2, :2]), noise_d, scratch[1, :2, :2]), scratch[2, :2, :2]), gain)
    _apply(gain, d, correction)
    _mul(gain, h, keep_cov)
    for r in range(ERRORS):
        for j in range(ERRORS):
            keep_cov[r, j] = (1.0 if r == j else 0.0) - keep_cov[r, j]
    # (Joseph's form: stays symmetric, positive)
    _add(_mul(_mul(keep_cov, matrix, scratch[0, :, :]), keep_cov.T, scratch[1, :, :]), _mul(_mul(gain, noise_d, scratch[2, :, :2]), gain.T, scratch[3, :, :]), matrix)
    for r in range(3):
        pose[r] += correction[r]
    for r in range(3, ERRORS):
        calibration[r] += correction[r]
    # the increment: both, corrected by the updated calibration, by their information
    _inverse(a_enc, i_enc)
    _inverse(a_mouse, i_mouse)
    _inverse(_add(i_enc, i_mouse, scratch[0, :2, :2]), weights)
    _mul(weights, i_enc, w_enc)
    _mul(weights, i_mouse, w_mouse)
    _apply(j_enc, calibration, applied)
    for k in range(2):
        updated_enc[k] = u_enc[k] + applied[k]
    _apply(j_mouse, calibration, applied)
    for k in range(2):
        updated_mouse[k] = u_mouse[k] + applied[k]
    _apply(w_enc, updated_enc, scratch[0, 0, :2])
    _apply(w_mouse, updated_mouse, scratch[0, 1, :2])
    for k in range(2):
        u[k] = scratch[0, 0, k] + scratch[0, 1, k]
    _add(_mul(w_enc, j_enc, scratch[0, :2, :]), _mul(w_mouse, j_mouse, scratch[1, :2, :]), jac)
    _weighed(w_enc, r_enc, w_mouse, r_mouse, noise, scratch)
    _weighed(w_enc, q_enc, w_mouse, q_mouse, lag[:, :], scratch)
    propagate(cov, pose[2], u[0], u[1], MID_ANGLE, jac, noise, work)
    s, alpha = u[0], u[1]
    if sliding:  # what the mouse's rotation added before the slide was seen is taken back
        alpha -= st[TAKEN]
        st[TAKEN] = 0.0
    else:
        st[TAKEN] += alpha - corrected_enc[1]
    return s, alpha, sliding


@numba.njit(cache=True, inline="always")
def _lay(pose: np.ndarray, s: float, alpha: float, end_heading: bool) -> None:
    """`ArcOdometry.update`: the pose after the arc, in place."""
    pose[0], pose[1], pose[2] = advance_one(pose[0], pose[1], pose[2], s, alpha, end_heading)


@numba.njit(cache=True)
def batch_step(
    tallies: np.ndarray, rows: np.ndarray, time: float, params: np.ndarray, state: np.ndarray, contact_steps: np.ndarray,
    calibration: np.ndarray, poses: np.ndarray, errors: np.ndarray, lags: np.ndarray, truth: np.ndarray, out: np.ndarray,
    cov_out: np.ndarray, work: np.ndarray,
) -> None:
    """One step of every robot's default estimators, in place: the compiled steps the Python
    estimators call (`bots.odometry.steps`), laid down as `ArcOdometry.update` lays them
    (`advance_one`). Where `out` has rows: out[i] = the true pose, then the estimates, and
    cov_out[i] their covariances (a run's log, one pass). `work`: scratch (`workspace`)."""
    if out.shape[0] != rows.shape[0] or cov_out.shape[0] != rows.shape[0]:
        raise ValueError("DefaultOdometry.update: out and cov_out must have a row for every robot of the batch")
    for i in range(rows.shape[0]):
        r, p, pose, cov = rows[i], params[i], poses[i], errors[i]
        if r >= tallies.shape[0] or tallies.shape[1] != 4:  # a kernel reads past an array's end without a word
            raise ValueError("DefaultOdometry.update: tallies must be (robots, 4) with a row for every robot of the batch")
        left, right = float(tallies[r, 0]), float(tallies[r, 1])
        for estimate in range(ENCODERS, FIRMWARE + 1):  # the encoders' arc along the mid-angle, then the firmware's along the end heading
            end_heading = estimate == FIRMWARE  # (a bool numba does not take for a constant: the step compiles once for both)
            s, alpha = encoder_step(p, pose[estimate, 2], cov[estimate], left, right, end_heading, work)
            _lay(pose[estimate], s, alpha, end_heading)
            sigma_encoders(p, sigma_block(state[i], estimate), left, right, end_heading)
        if p[HAS_MOUSE] == 0.0:
            continue
        forward, lateral = float(tallies[r, 2]), float(tallies[r, 3])
        s, alpha = mouse_step(p, pose[MOUSE, 2], cov[MOUSE], forward, lateral, work)
        _lay(pose[MOUSE], s, alpha, False)
        sigma_mouse(p, sigma_block(state[i], MOUSE), forward, lateral)
        s_enc, alpha_enc, var = turn_check(p, left, right, s, alpha)
        watch_slides(p, slide_block(state[i], MOUSE), cov[MOUSE], alpha - alpha_enc, var, alpha_enc, s_enc, time)
        s, alpha, sliding = fused_step(p, state[i], pose[FUSED], calibration[i], cov[FUSED], lags[i, FUSED], left, right, forward, lateral, time, work)
        contact_steps[i] += sliding
        _lay(pose[FUSED], s, alpha, False)
    for i in range(out.shape[0]):
        if rows[i] >= truth.shape[0]:
            raise ValueError("DefaultOdometry.update: truth must have a row for every robot of the batch")
        for c in range(3):  # (element by element: an array assignment compiles numba's whole shape-mismatch message)
            out[i, 0, c] = truth[rows[i], c]
            for j in range(ESTIMATES):
                out[i, 1 + j, c] = poses[i, j, c]
        estimates = ESTIMATES if params[i, HAS_MOUSE] != 0.0 else FIRMWARE + 1
        for j in range(estimates):
            pose_covariance(errors[i, j], poses[i, j, 2], lags[i, j], cov_out[i, j])
            if j != FUSED:
                add_spread(sigma_block(state[i], j), SIGMAS if j != MOUSE else 2, poses[i, j], cov_out[i, j])
