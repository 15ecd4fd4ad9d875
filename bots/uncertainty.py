"""How sure an odometry estimate is: its error covariance, propagated step by step from the
sensors' noise model, in compiled kernels shared by the Python estimators and the batch.

The error state of every estimator has ERRORS entries: the pose error (x, y m; heading rad) and
four relative calibration errors the robot's own code cannot see (left and right wheel scale,
track width, mouse resolution), each constant through a run. A step's increment (arc length s,
heading change alpha) is wrong by `jac @ errors + n`, n ~ `noise` (2, 2); laying it down moves the
pose error by the increment's Jacobians (the mid-angle chord of seed 002 eq 1.12, or the
firmware's end heading), as in Chong and Kleeman 1997 ("Accurate odometry and error modelling for
a mobile robot", their per-wheel distance variance growing with the distance rolled, plus the
systematic errors of UMBmark as constant states, which make the pose covariance of a wrong track
width grow with the rotation and that of a wheel mismatch with distance squared).

The kernels of this model (`wheel_terms`, `mouse_terms`, `propagate`, `pose_covariance`) live in
`bots.odometry.propagation`, which every estimator's compiled step calls.

Quantisation is not a random walk here: counts are carried, so each channel's count is off the
truth by less than one count at any time and that never adds up. Where the counter started within
a count is unknown (a real wheel stops anywhere: `EncoderSpec.start_phase`), so the count is
floor(true + phase) with the phase uniform: its error has zero mean and, over where the truth ends
within a count, variance count²/6 (COUNT_VARIANCE; a counter started on an edge would lag by half
a count on average instead, a bias). It is added to the reported pose covariance
(`pose_covariance`), never to the propagated one; the dead reckonings whose calibration sigma
points carry split it into where the counters stand now (reported so, count²/12) and where they
started (count²/12), an offset propagated from the start, whose heading part turns every later
move (`bots.odometry.base.phase_offset`).

The believed noise (`Belief.of`) is the robot's own belief (`bots.spec.BeliefSpec`): its stated
tolerances, or what a user or a calibration gave; never the errors the simulation draws, which a
real robot's estimator cannot know (tests/test_uncertainty.py changes them and sees every reported
covariance stay the same).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from bots.spec import RobotSpec

COUNT_VARIANCE = 1.0 / 6.0
"""Variance (counts²) of a carried count's error against the truth, its start phase unknown: for a
truth ending a fraction f into a count the error is -f or 1 - f (variance f (1 - f)), 1/6 over f."""


class ErrorStates(NamedTuple):
    """Each entry's place in an estimator's error state: the pose error (x, y m; heading rad), then
    the relative calibration errors (each wheel's scale, the track's, the mouse resolution's)."""

    x: int
    y: int
    heading: int
    left_scale: int
    right_scale: int
    track_scale: int
    mouse_scale: int


ERROR = ErrorStates(*range(len(ErrorStates._fields)))
"""Where each error lies in the state (`cov[ERROR.heading, ERROR.heading]`); a compiled step reads it as a constant."""
ERRORS = len(ERROR)
"""Entries of an estimator's error state."""
COVARIANCE_FIELDS = ("cov_xx", "cov_xy", "cov_xt", "cov_yy", "cov_yt", "cov_tt")
"""The six distinct entries of a pose covariance (m², m·rad, rad²), in the order `pose_covariance` writes."""


@dataclass(frozen=True)
class Belief:
    """The noise an estimator assumes (per metre where random; relative where scales), as
    `bots.spec` states the world's processes.

    slip_var: variance of a wheel's arc per metre rolled (m² per m, slip_std²); tick_rate:
    probability that a counted tick is one off; wheel_scale_std, track_std, mouse_scale_std:
    standard deviation of the unknown relative errors of each wheel's diameter, the track width
    and the mouse's resolution; mouse_var: variance of each mouse axis per metre of floor passed
    (m² per m, noise_std²)."""

    slip_var: float = 0.0
    tick_rate: float = 0.0
    wheel_scale_std: float = 0.0
    track_std: float = 0.0
    mouse_var: float = 0.0
    mouse_scale_std: float = 0.0

    @classmethod
    def of(cls, robot: RobotSpec) -> Belief:
        """The robot's own belief (`RobotSpec.belief`, its stated tolerances or what a user or a
        calibration gave), in this model's terms; never the simulated errors."""
        said = robot.belief
        return cls(
            slip_var=said.slip_std**2,
            tick_rate=said.tick_noise,
            wheel_scale_std=said.wheel_diameter_std,
            track_std=said.track_std,
            mouse_var=0.0 if robot.mouse is None else said.mouse_noise_std**2,
            mouse_scale_std=0.0 if robot.mouse is None else said.mouse_scale_std,
        )

    def prior(self) -> np.ndarray:
        """(ERRORS, ERRORS) the error covariance at the start: the pose known, the scales not."""
        cov = np.zeros((ERRORS, ERRORS))
        cov[ERROR.left_scale, ERROR.left_scale] = cov[ERROR.right_scale, ERROR.right_scale] = self.wheel_scale_std**2
        cov[ERROR.track_scale, ERROR.track_scale] = self.track_std**2
        cov[ERROR.mouse_scale, ERROR.mouse_scale] = self.mouse_scale_std**2
        return cov


def square(entries: np.ndarray) -> np.ndarray:
    """(..., 3, 3) covariance matrices from their (..., 6) COVARIANCE_FIELDS entries."""
    if isinstance(entries, np.ndarray) and entries.shape == (6,):  # one estimator's, every step: without numpy's stacking (20 us)
        xx, xy, xt, yy, yt, tt = entries.tolist()
        return np.array(((xx, xy, xt), (xy, yy, yt), (xt, yt, tt)))
    xx, xy, xt, yy, yt, tt = np.moveaxis(np.asarray(entries, dtype=np.float64), -1, 0)
    return np.stack([np.stack([xx, xy, xt], -1), np.stack([xy, yy, yt], -1), np.stack([xt, yt, tt], -1)], -2)


def entries_of(cov: np.ndarray) -> np.ndarray:
    """(6,) COVARIANCE_FIELDS entries of a covariance's pose block (its first three rows and
    columns): `square`'s inverse."""
    return np.asarray(cov, dtype=np.float64)[np.triu_indices(3)]
