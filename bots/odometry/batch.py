"""The default odometry estimators of every robot of a run, stepped in one compiled pass per step.

`bots.odometry`'s estimators step one robot at a time in Python floats: a run's four defaults per
robot cost more than the world's own step. `DefaultOdometry` holds the defaults of all robots that
use them (`default_estimators` of a robot without a general chassis) as arrays and steps them in
one numba kernel fed straight from the world's per-step tallies. The kernel calls the same
compiled steps as the Python estimators (`bots.odometry.steps`) and lays the pose with the
compiled twin of their `advance`, so its estimates and covariances equal theirs bit for bit
(tests/test_odometry_batch.py holds the two together); the Python classes stay what a robot
given its own `estimators=` runs. Parameters are read from reset Python estimators,
so every formula for them (tolerances, believed geometry) has one home, `bots.odometry.base`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from bots.odometry.defaults import default_estimators
from bots.odometry.steps import ENCODERS, ESTIMATES, FUSED, MOUSE, PARAMS, SIGMA_POSES, SIGMAS, batch_step, fresh_state, workspace
from bots.spec import RobotSpec
from bots.uncertainty import COVARIANCE_FIELDS, ERRORS

COVARIANCES = len(COVARIANCE_FIELDS)


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
        self.params = np.zeros((n, PARAMS))
        self.state = np.repeat(fresh_state()[None], n, axis=0)
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
            self.params[k] = chosen[ENCODERS].params
            if len(chosen) > MOUSE:
                self.state[k] = chosen[FUSED].state
            for j in range(min(len(chosen), FUSED)):  # the dead reckoners' sigma points (`bots.odometry.steps.sigma_block`)
                start = SIGMA_POSES + j * SIGMAS * 3
                self.state[k, start : start + SIGMAS * 3] = chosen[j].sigmas.ravel()
        self._out = np.zeros((n, 1 + ESTIMATES, 3))  # (where `update` is not given a run's row)
        self._cov_out = np.zeros((n, ESTIMATES, COVARIANCES))
        self._truth = np.zeros((max(self.rows.max(initial=-1) + 1, 0), 3))
        self._work = workspace()
        # the kernel for these arrays' types, called without numba's dispatch (a third of its cost),
        # as `sim.world.compiling.compiled_for` does it for the world (bots/ does not import the world)
        arguments = (np.zeros((1, 4), np.int64), self.rows, 0.0, self.params, self.state, self.contact_steps, self.calibration,
                     self.poses, self.errors, self.lags, self._truth, self._out, self._cov_out, self._work)  # fmt: skip
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
        self._step(tallies, self.rows, time, self.params, self.state, self.contact_steps, self.calibration,
                   self.poses, self.errors, self.lags, truth, out, cov_out, self._work)  # fmt: skip


