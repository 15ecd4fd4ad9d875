"""The odometry's packed tables, each declared once (`sim.kinematics.packed`), and the default
estimates by name.

The compiled steps (`encoder`, `mouse`, `fused`, stepped together by `batch`) take a robot's
parameters and state as one row each and read them by name (`p.track`, `st.mouse_watch.peak`);
the default estimates of a batch lie along an axis in the order of `ESTIMATES`, and code reaches
one by its name (`poses[i, ESTIMATE.fused]`), never by a number typed by hand.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from bots.uncertainty import ERRORS
from sim.kinematics.packed import Field, Table


class Estimates(NamedTuple):
    """Each default estimate's place along a batch's estimate axis, in the order of
    `bots.odometry.defaults.default_estimators` (the dead reckoners first: they alone have sigma
    points)."""

    encoders: int
    firmware: int
    mouse: int
    fused: int


ESTIMATE = Estimates(*range(len(Estimates._fields)))
"""Where each default estimate lies (`poses[i, ESTIMATE.mouse]`); a compiled step reads it as a constant."""
ESTIMATES = len(ESTIMATE)
"""Default estimates of a robot with a mouse that sees rotation (one without has the first two)."""
ENCODERS_ONLY = ESTIMATE.firmware + 1
"""Default estimates of a robot without such a mouse: the encoders' and the firmware's."""
DEAD_RECKONERS = ESTIMATE.fused
"""The estimates before the fused one, each with its sigma points (`STATE.sigmas`)."""
SIGMA_SPREAD = math.sqrt(3.0)
"""Standard deviations from the estimate to a sigma point along each calibration error: the nodes
of Gauss-Hermite quadrature with three points (0, +-sqrt(3)), exact for a Gaussian's moments up
to the fifth."""
NODES = (0.0, SIGMA_SPREAD, -SIGMA_SPREAD)
"""The three nodes (standard deviations) of each calibration error; a point's base-3 digits pick one per error."""
NODE_WEIGHTS = (2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0)
"""Their weights; a point weighs the product of its nodes' (`bots.odometry.propagation.point_weight`)."""
_MOUSE_NODES, _MOUSE_WEIGHTS = np.polynomial.hermite_e.hermegauss(7)
MOUSE_NODES = tuple(float(x) for k, x in enumerate(_MOUSE_NODES) if k != 3)
"""The mouse's resolution error, its one calibration error, on seven nodes of Gauss-Hermite
quadrature (standard deviations, up to +-3.75) but the middle one (the estimate itself): three
nodes span only a plane of the pose's three dimensions, and a resolution off by a few per cent,
turned through five laps of the line course (1,800 degrees), puts the pose on a curve that bends
out of it. With three nodes the mouse's mean NEES at the end over 40 drawn robots read 6.8-11.3
on the line course (follow_line) and in the empty arena (wander), their median 4.2-5.2; with
seven 3.3-4.6 (docs/odometry.md, "Why sets of 40 stray")."""
MOUSE_NODE_WEIGHTS = tuple(float(w) for k, w in enumerate(_MOUSE_WEIGHTS / _MOUSE_WEIGHTS.sum()) if k != 3)
"""Their weights (the estimate weighs the rest)."""
MOUSE_SIGMAS = len(MOUSE_NODES)
"""The mouse's sigma points."""
SIGMAS = 3**3 - 1
"""Sigma points of a dead-reckoning estimator: every combination of the nodes of its calibration
errors but all at 0 (the estimate itself): the encoders' 26 of three (left wheel, right wheel,
track); the mouse has its own rule (`MOUSE_NODES`). The combinations carry how the errors act
together: with only the 2 a error (6 in all), a robot of the belief's spread turns its heading tens
of degrees in the maze, its position's error curves, and the points' spread missed a direction
the errors take (their mean NEES over robots drawn from the belief, calibration alone: 170-370
where 3 is right; with the 26: 3.1)."""
RESIDUALS = 4
"""Counters whose residual the fused filter carries: the two encoders and the mouse's two axes."""
HYPOTHESIS_WEIGHT = 1.0
"""The weight of a slide watch's hypothesis (`bots.odometry.mouse.watch_slides`) in its
estimate's covariance: the second moment of an error as large as its offset. The watch sees the
slide's size and sign but not which sensor was wrong; the estimate is taken as wrong by all of it."""

PARAMETERS = Table(
    "per robot: what its estimators believe, passed to the compiled steps rather than compiled in "
    "(numba's cache would not see a module's constants change); the fused estimator's tolerances "
    "and memories are `bots.odometry.base`'s",
    # the encoders' (and everyone's) believed drive
    Field("tick_left", 1, "m of rim per tick, left wheel"),
    Field("tick_right", 1, "m of rim per tick, right wheel"),
    Field("track", 1, "m, the believed track"),
    # the mouse
    Field("per_metre", 1, "mouse counts per m"),
    Field("mount_x", 1, "m, the mouse's x in the body frame"),
    Field("mount_y", 1, "m, the mouse's y in the body frame"),
    # the fused estimator's detectors (`FusedOdometry`)
    Field("tolerance", 1, "m, the slip detector's quantisation band"),
    Field("turn_tolerance", 1, "rad, the slide detector's band"),
    Field("memory", 1, "s, TURN_MEMORY"),
    Field("gate", 1, "standard deviations, GATE_SIGMAS"),
    Field("has_mouse", 1, "the robot has the mouse estimators, not only the encoders'", np.bool_),
    # the believed noise (`bots.uncertainty.Belief`)
    Field("slip_var", 1, "relative slip variance (m² per m)"),
    Field("tick_var_left", 1, "m² per m, spurious ticks, left wheel"),
    Field("tick_var_right", 1, "m² per m, spurious ticks, right wheel"),
    Field("mouse_var", 1, "m² per m, a mouse axis's reading"),
    Field("distance_memory", 1, "m, SLIP_MEMORY"),
    # the believed calibration errors' standard deviations (the sigma points' offsets)
    Field("wheel_std", 1, "relative, each wheel's scale"),
    Field("track_std", 1, "relative, the track's"),
    Field("mouse_scale_std", 1, "relative, the mouse resolution's"),
    # the slide watch (`bots.odometry.mouse.watch_slides`)
    Field("slide_memory", 1, "s, SLIDE_WATCH_MEMORY"),
    Field("slide_gate", 1, "standard deviations, SLIDE_WATCH_GATE"),
)
SLIDE_WATCH = Table(
    "a slide watch's sums (`bots.odometry.mouse.watch_slides`), of the mouse or the fused estimate",
    Field("disagreement", 1, "rad, the mouse's rotation beyond the encoders', summed"),
    Field("turning", 1, "rad, the encoders' net turn, summed"),
    Field("travel", 1, "m, the encoders' distance, summed"),
    Field("peak", 1, "rad, the largest disagreement of the slide going on (0: none)"),
    Field("time", 1, "s, of the last step (nan: none yet)"),
    Field("var", 1, "rad², the disagreement's random variance, summed"),
    Field("pending", 1, "rad, the disagreement not yet taken as a slide (while within the band), summed"),
    Field("hypothesis", 3, "the estimate's pose had every turn the watch saw been a slide (x, y m, heading rad)"),
)
STATE = Table(
    "per robot: what the compiled steps carry from step to step",
    # the fused estimator's detectors, as `FusedOdometry` describes them
    Field("disagreement", 1, "m, the encoders' distance beyond the mouse's, over the last distance_memory"),
    Field("turn_disagreement", 1, "rad, the mouse's rotation beyond the encoders', over the last memory"),
    Field("taken", 1, "rad, what the mouse's rotation added since the last slide"),
    Field("turning", 1, "rad, the encoders' turning over the last memory"),
    Field("time", 1, "s, of the last step (nan: none yet)"),
    Field("travel", 1, "m, the mouse's distance over the last distance_memory"),
    Field("turn_travel", 1, "m, the encoders' distance over the last memory"),
    Field("disagreement_var", 1, "m², the distance disagreement's random variance"),
    Field("turn_var", 1, "rad², the rotation disagreement's random variance"),
    Field("sigmas", DEAD_RECKONERS, "the sigma points' poses (SIGMAS, 3) of each dead reckoner, by ESTIMATE", np.dtype((np.float64, (SIGMAS, 3)))),
    Field("sigma_noises", DEAD_RECKONERS, "the sigma points' random parts (COVARIANCE_FIELDS, SIGMAS) of each dead reckoner, by ESTIMATE",
          np.dtype((np.float64, (6, SIGMAS)))),
    Field("turns", DEAD_RECKONERS, "scratch: their sigma points' last arc length and direction's cosine and sine (3, SIGMAS)", np.dtype((np.float64, (3, SIGMAS)))),
    Field("mouse_watch", 1, "the mouse estimate's slide watch", SLIDE_WATCH.dtype),
    Field("fused_watch", 1, "the fused estimate's slide watch", SLIDE_WATCH.dtype),
    # the fused estimator's counters' residuals (`bots.odometry.fused.residual_update`)
    Field("residual", RESIDUALS, "m, each counter's estimated residual: what it moved beyond its last count, less half a count (left, right tick, forward, lateral count)"),
    Field("residual_cov", 1, "m², their covariance", np.dtype((np.float64, (RESIDUALS, RESIDUALS)))),
    Field("residual_cross", 1, "their covariance with the error state (ERRORS, RESIDUALS)", np.dtype((np.float64, (ERRORS, RESIDUALS)))),
)

class Planes(NamedTuple):
    """Each scratch plane's place in a `workspace` (WORK planes of (ERRORS, ERRORS)), by what a
    compiled step keeps there: `propagate`'s own three, the increment's Jacobian and noise a step
    hands it, the fused step's (`bots.odometry.fused.fused_step`) intermediates, and last
    SCRATCH_PLANES of temporaries, each used within one expression."""

    propagate_a: int  # propagate: d pose' / d (pose, errors)
    propagate_rows: int  # propagate: a @ cov
    propagate_pose: int  # propagate: the pose block of a @ cov @ a^T
    increments: int  # fused: the step's increments (rows by INCREMENT)
    updates: int  # fused: the update's correction and the increments it corrects (rows by UPDATE)
    j_enc: int  # fused: the encoders' increment's Jacobian on the errors, its random noise,
    r_enc: int
    q_enc: int  # its quantisation,
    a_enc: int  # and the two together
    j_mouse: int  # fused: the same of the mouse's
    r_mouse: int
    q_mouse: int
    a_mouse: int
    h: int  # fused: the disagreement's Jacobian on the errors, its noise,
    noise_d: int
    ph: int  # the errors' rows of P h^T,
    gain: int  # and the Kalman gain
    i_enc: int  # fused: each increment's information, their weights
    i_mouse: int
    weights: int
    w_enc: int
    w_mouse: int
    residual_ph: int  # fused: the residuals' rows of P h^T (before, after the step; columns 0:2, 2:4), the map of a residual to d (rows 4, 5)
    residual_gain: int  # fused: the residual after's rows of the gain (columns 0:2), a new residual's variance (row 4)
    jac: int  # every step: the increment's Jacobian on the errors and its noise, for `propagate`
    noise: int
    scratch: int  # the first of SCRATCH_PLANES


PLANE = Planes(*range(len(Planes._fields)))
"""Where each scratch plane lies in a `workspace` (`work[PLANE.gain, :, :2]`)."""
SCRATCH_PLANES = 4
"""Temporary planes after PLANE.scratch (`_weighed` in `bots.odometry.fused` takes four)."""
WORK = PLANE.scratch + SCRATCH_PLANES
"""Scratch planes of (ERRORS, ERRORS) a step uses at most."""


class Increments(NamedTuple):
    """The rows of plane PLANE.increments (each an increment (s, alpha), its first two entries)."""

    enc: int  # the encoders' increment
    mouse: int  # the mouse's
    corrected_enc: int  # each corrected by the calibration estimated so far
    corrected_mouse: int
    d: int  # their difference
    u: int  # the increment laid down
    applied: int  # a Jacobian applied to the calibration


INCREMENT = Increments(*range(len(Increments._fields)))
"""Where each increment lies in plane PLANE.increments."""


class Updates(NamedTuple):
    """The rows of plane PLANE.updates."""

    correction: int  # the update's correction of the pose and the calibration (ERRORS entries)
    updated_enc: int  # the encoders' increment, corrected by the updated calibration (two entries)
    updated_mouse: int  # the mouse's


UPDATE = Updates(*range(len(Updates._fields)))
"""Where each row lies in plane PLANE.updates."""


class ResidualRows(NamedTuple):
    """The rows of planes PLANE.residual_ph and PLANE.residual_gain after the counters' own (one a
    counter, RESIDUALS of them)."""

    map: int  # residual_ph: the map M of each counter's (before - after) to the disagreement d (two rows)
    variance: int  # residual_gain: a new residual's variance, one entry a counter


RESIDUAL_ROW = ResidualRows(RESIDUALS, RESIDUALS)
"""Where each lies in its plane."""


class Counts(NamedTuple):
    """One step's readings an estimator takes (floats): encoder ticks, mouse counts in the sensor frame."""

    left: float
    right: float
    forward: float
    lateral: float


TALLY = Counts(*range(len(Counts._fields)))
"""Where each count lies in a row of a step's tallies (`SensorFrame.tallies`, (robots,
len(TALLY)) int64: the registry's kinds of its tallies array, encoder ticks then mouse counts)."""


class Estimate(NamedTuple):
    """One estimate a compiled step moves, in place: its pose (3,), its error covariance (ERRORS,
    ERRORS) and the quantisation lag (2, 2) reported beside it."""

    pose: np.ndarray
    cov: np.ndarray
    lag: np.ndarray


def fresh_state() -> np.void:
    """A robot's STATE row before its first step: no time seen yet (nan), all else zero (the
    sigma points are set to the start pose by their estimators)."""
    state = STATE.new(1)[0]
    state["time"] = state["mouse_watch"]["time"] = state["fused_watch"]["time"] = math.nan
    return state


def watch_of(state: np.void, estimate: int) -> np.void:
    """The slide watch of estimate ESTIMATE.mouse or ESTIMATE.fused in a STATE row (a view), or
    None for an estimate without one."""
    return {ESTIMATE.mouse: state["mouse_watch"], ESTIMATE.fused: state["fused_watch"]}.get(estimate)


def workspace() -> np.ndarray:
    """Scratch for the compiled steps (WORK planes of (ERRORS, ERRORS)): their intermediates live
    there, not in arrays allocated every step (which cost more than the arithmetic)."""
    return np.zeros((WORK, ERRORS, ERRORS))
