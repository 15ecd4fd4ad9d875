"""The default odometry estimators of every robot of a run, stepped in one compiled pass per step.

`bots.odometry`'s estimators step one robot at a time in Python floats: a run's four defaults per
robot cost more than the world's own step. `DefaultOdometry` holds the defaults of all robots that
use them (`default_estimators` of a robot without a general chassis) as arrays and steps them in
one numba kernel fed straight from the world's per-step tallies. The kernel calls the same
compiled steps as the Python estimators (`encoder`, `mouse`, `fused`) and lays the pose with the
compiled twin of their `advance`, so its estimates and covariances equal theirs bit for bit
(tests/test_odometry_batch.py holds the two together); the Python classes stay what a robot
given its own `estimators=` runs. Parameters are read from reset Python estimators,
so every formula for them (tolerances, believed geometry) has one home, `bots.odometry.base`.

The odometry's kernels divide as numpy does (error_model "numpy": x / 0.0 is inf or nan, not a
ZeroDivisionError), which spares numba a test and a raise compiled at every division (some 5-7 %
of their first compile): their divisors are believed geometry, which a reset already divides by in
Python, and variances that hold a positive quantisation term.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

import numba
import numpy as np

from bots.odometry.defaults import default_estimators
from bots.odometry.encoder import encoder_step, sigma_encoders_both
from bots.odometry.fused import fused_step
from bots.odometry.layout import DEAD_RECKONERS, ENCODERS_ONLY, ESTIMATE, ESTIMATES, HYPOTHESIS_WEIGHT, PARAMETERS, PLANE, SIGMAS, STATE, TALLY, Counts, Estimate, fresh_state, workspace
from bots.odometry.mouse import MOUSE_SIGMAS, mouse_step, sigma_mouse, turn_check, watch_slides
from bots.odometry.propagation import add_offset, add_point_noise, add_spread, lay, pose_covariance
from bots.spec import RobotSpec
from bots.uncertainty import COVARIANCE_FIELDS, ERROR, ERRORS

COVARIANCES = len(COVARIANCE_FIELDS)


class Batch(NamedTuple):
    """The arrays `batch_step` moves, one row per robot of the batch: its row in the tallies, its
    PARAMETERS and STATE rows (`bots.odometry.layout`), the fused estimator's contact steps and
    calibration (ERRORS,), and per estimate (along ESTIMATE) the pose (3,), error covariance
    (ERRORS, ERRORS) and quantisation lag (2, 2)."""

    rows: np.ndarray
    params: np.ndarray
    state: np.ndarray
    contact_steps: np.ndarray
    calibration: np.ndarray
    poses: np.ndarray
    errors: np.ndarray
    lags: np.ndarray


@numba.njit(cache=True, error_model="numpy")
def batch_step(batch: Batch, tallies: np.ndarray, time: float, truth: np.ndarray, out: np.ndarray, cov_out: np.ndarray, work: np.ndarray) -> None:
    """One step of every robot's default estimators by the `tallies` read at `time` (s), in place:
    the compiled steps the Python estimators call, laid down as `ArcOdometry.update` lays them
    (`advance_one`). Where `out` has rows: out[i] = the true pose (its row of `truth`), then the
    estimates, and cov_out[i] their covariances (a run's log, one pass). `work`: scratch
    (`workspace`)."""
    rows, params, state, poses, errors, lags = batch.rows, batch.params, batch.state, batch.poses, batch.errors, batch.lags
    if out.shape[0] != rows.shape[0] or cov_out.shape[0] != rows.shape[0]:
        raise ValueError("DefaultOdometry.update: out and cov_out must have a row for every robot of the batch")
    for i in range(rows.shape[0]):
        r, p, st, pose, cov = rows[i], params[i], state[i], poses[i], errors[i]
        if r >= tallies.shape[0] or tallies.shape[1] != len(TALLY):  # a kernel reads past an array's end without a word
            raise ValueError("DefaultOdometry.update: tallies must be (robots, 4) with a row for every robot of the batch")
        counts = Counts(float(tallies[r, TALLY.left]), float(tallies[r, TALLY.right]), float(tallies[r, TALLY.forward]), float(tallies[r, TALLY.lateral]))
        for estimate in (ESTIMATE.encoders, ESTIMATE.firmware):  # the encoders' arc along the mid-angle, then the firmware's along the end heading
            end_heading = estimate == ESTIMATE.firmware  # (a bool numba does not take for a constant: the step compiles once for both)
            s, alpha = encoder_step(p, pose[estimate, 2], cov[estimate], counts.left, counts.right, end_heading, work)
            lay(pose[estimate], s, alpha, end_heading)
        sigma_encoders_both(p, st, counts.left, counts.right, work[PLANE.noise, :2, :2])
        if not p.has_mouse:
            continue
        mouse = ESTIMATE.mouse
        s, alpha = mouse_step(p, pose[mouse, 2], cov[mouse], counts.forward, counts.lateral, work)
        lay(pose[mouse], s, alpha, False)
        sigma_mouse(p, st.sigmas[mouse], st.sigma_noises[mouse], counts.forward, counts.lateral, work[PLANE.noise, :2, :2], st.turns[mouse])
        s_enc, alpha_enc, var = turn_check(p, counts.left, counts.right, s, alpha)
        lay(st.mouse_watch.hypothesis, s, alpha, False)
        cov[mouse, ERROR.heading, ERROR.heading] += watch_slides(p, st.mouse_watch, alpha - alpha_enc, var, alpha_enc, s_enc, time)[1]
        fused = ESTIMATE.fused
        s, alpha, sliding = fused_step(p, st, Estimate(pose[fused], cov[fused], lags[i, fused]), batch.calibration[i], counts, time, work)
        batch.contact_steps[i] += sliding
        lay(pose[fused], s, alpha, False)
        lay(st.fused_watch.hypothesis, s, alpha, False)
    for i in range(out.shape[0]):
        if rows[i] >= truth.shape[0]:
            raise ValueError("DefaultOdometry.update: truth must have a row for every robot of the batch")
        for c in range(3):  # (element by element: an array assignment compiles numba's whole shape-mismatch message)
            out[i, 0, c] = truth[rows[i], c]
            for j in range(ESTIMATES):
                out[i, 1 + j, c] = poses[i, j, c]
        for j in range(ESTIMATES if params[i].has_mouse else ENCODERS_ONLY):
            pose_covariance(errors[i, j], poses[i, j, 2], lags[i, j], cov_out[i, j])
            if j != ESTIMATE.fused:
                count = SIGMAS if j != ESTIMATE.mouse else MOUSE_SIGMAS
                add_spread(state[i].sigmas[j], count, poses[i, j], cov_out[i, j])
                add_point_noise(state[i].sigma_noises[j], count, errors[i, j], cov_out[i, j])
        if params[i].has_mouse:  # the slide watches' hypotheses (`bots.odometry.mouse.watch_slides`), as arrays
            # of the sigma points' type (`add_spread`'s rows), not a record's own: one compile of `add_offset`
            add_offset(state[i].mouse_watch.hypothesis[:], poses[i, ESTIMATE.mouse], HYPOTHESIS_WEIGHT, cov_out[i, ESTIMATE.mouse])
            add_offset(state[i].fused_watch.hypothesis[:], poses[i, ESTIMATE.fused], HYPOTHESIS_WEIGHT, cov_out[i, ESTIMATE.fused])


def batched(robot: RobotSpec) -> bool:
    """Whether `DefaultOdometry` steps this robot's default estimators (a general chassis's are
    `bots.odometry.chassis`'s, stepped in Python)."""
    return robot.chassis is None


def kernel_jobs() -> list[tuple[Any, tuple]]:
    """The kernel `DefaultOdometry` steps with and arguments of the types it is called with (of a
    batch of no robots: types are kinds, not sizes), for a caller that starts its compile before
    any robot is placed (`sim.world.compiling.start`: a run, first thing); a `DefaultOdometry`
    made later asks for the same job."""
    jobs: list[tuple[Any, tuple]] = []
    DefaultOdometry([], np.zeros((0, 3)), [], jobs.extend)
    return jobs


class DefaultOdometry:
    """The default estimators of several robots (each `batched`), reset at their start poses.

    `poses` (n, ESTIMATES, 3) holds each robot's estimates, updated in place by `update`, and
    `errors` (n, ESTIMATES, ERRORS, ERRORS) their error covariances; a robot without a mouse that
    sees rotation has only the first two (`names`). `calibration` (n, ERRORS) the fused
    estimator's calibration estimate, `contact_steps` (n,) its steps of wall contact, as
    `FusedOdometry`'s."""

    def __init__(self, robots: Sequence[RobotSpec], poses: np.ndarray, rows: Sequence[int], compiling: Callable[[list[tuple]], Any] | None = None):
        """`poses` (n, 3) the start poses; `rows` each robot's row in the tallies `update` gets.
        `compiling`: starts compiling [(kernel, arguments)] and answers something whose `wait()`
        gives them compiled (`sim.world.compiling.start`: in compile processes, beside the
        world's kernels), waited for at the first update; None: compiled here and now."""
        n = len(robots)
        self.rows = np.array(rows, dtype=np.int64).reshape(n)
        self.params = PARAMETERS.new(n)
        self.state = STATE.new(n)
        self.contact_steps = np.zeros(n, dtype=np.int64)
        self.calibration = np.zeros((n, ERRORS))
        self.poses = np.repeat(np.asarray(poses, dtype=np.float64).reshape(n, 1, 3), ESTIMATES, axis=1)
        self.errors = np.zeros((n, ESTIMATES, ERRORS, ERRORS))
        self.lags = np.zeros((n, ESTIMATES, 2, 2))
        self.names: list[list[str]] = []
        for k, (robot, pose) in enumerate(zip(robots, self.poses[:, 0])):
            chosen = default_estimators(robot)
            for j, estimator in enumerate(chosen):
                estimator.reset(robot, pose)
                self.errors[k, j], self.lags[k, j] = estimator.errors, estimator.lag
            self.names.append([estimator.name for estimator in chosen])
            self.params[k] = chosen[ESTIMATE.encoders].params
            self.state[k] = chosen[ESTIMATE.fused].state if len(chosen) == ESTIMATES else fresh_state()
            for j, estimator in enumerate(chosen[:DEAD_RECKONERS]):  # the dead reckoners' sigma points and their random parts
                self.state[k]["sigmas"][j] = estimator.sigmas
                self.state[k]["sigma_noises"][j] = estimator.noises
        self.batch = Batch(self.rows, self.params, self.state, self.contact_steps, self.calibration, self.poses, self.errors, self.lags)
        self._out = np.zeros((n, 1 + ESTIMATES, 3))  # (where `update` is not given a run's row)
        self._cov_out = np.zeros((n, ESTIMATES, COVARIANCES))
        self._truth = np.zeros((max(self.rows.max(initial=-1) + 1, 0), 3))
        self._work = workspace()
        # the kernel for these arrays' types, called without numba's dispatch (a third of its cost),
        # as `sim.world.compiling.compiled_for` does it for the world (bots/ does not import the world)
        arguments = (self.batch, np.zeros((1, 4), np.int64), 0.0, self._truth, self._out, self._cov_out, self._work)
        if compiling is None:
            self._step = batch_step.compile(tuple(batch_step.typeof_pyval(argument) for argument in arguments))
        else:
            self._compiling = compiling([(batch_step, arguments)])
            self._step = self._first_step

    def _first_step(self, *arguments: Any) -> None:
        """The first update: the kernel, once its compile is done, for this and every later one."""
        (self._step,) = self._compiling.wait()
        self._step(*arguments)

    def rows_of(self, k: int) -> np.ndarray:
        """The `k`-th robot's estimates, (estimates, 3), a view into `poses` in the order of
        `names[k]` (valid for the batch's life: `update` writes in place)."""
        return self.poses[k, : len(self.names[k])]

    def update(self, tallies: np.ndarray, time: float, truth: np.ndarray | None = None, out: np.ndarray | None = None,
               cov_out: np.ndarray | None = None) -> None:  # fmt: skip
        """Step every robot's estimates by one step's readings: `tallies` (rows, 4) int64 encoder
        ticks (left, right) then mouse counts (forward, left) per robot (`SensorFrame.tallies`), read
        at `time` (s). With `out` (n, 1 + ESTIMATES, 3) and `cov_out` (n, ESTIMATES, COVARIANCES),
        a run's sample row, each robot's true pose (its row of `truth`, (rows, 3)), estimates and
        their covariances (`bots.uncertainty.pose_covariance`) are written there too, in the same pass."""
        tallies = np.ascontiguousarray(tallies, dtype=np.int64)  # (the types `_step` was compiled for)
        if out is None:
            truth, out, cov_out = self._truth, self._out, self._cov_out
        else:
            truth, out = np.ascontiguousarray(truth, dtype=np.float64), np.ascontiguousarray(out, dtype=np.float64)
            cov_out = np.ascontiguousarray(cov_out, dtype=np.float64)
        self.update_into(tallies, float(time), truth, out, cov_out)

    def update_into(self, tallies: np.ndarray, time: float, truth: np.ndarray, out: np.ndarray, cov_out: np.ndarray) -> None:
        """`update` with `out` and `cov_out`, for a caller whose arrays already have the types the
        kernel was compiled for (C-ordered: int64 tallies, float64 truth and outputs; a float time),
        as a run's columns do: no conversions, which would cost as much as the kernel's work."""
        self._step(self.batch, tallies, time, truth, out, cov_out, self._work)


