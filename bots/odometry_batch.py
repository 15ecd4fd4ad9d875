"""The default odometry estimators of every robot of a run, stepped in one compiled pass per step.

`bots.odometry`'s estimators step one robot at a time in Python floats: a run's four defaults per
robot cost more than the world's own step. `DefaultOdometry` holds the defaults of all robots that
use them (`default_estimators` of a robot without a general chassis) as arrays and steps them in
one numba kernel fed straight from the world's per-step tallies. The kernel does the Python
estimators' operations in the same order, nothing fused, so its estimates equal theirs bit for bit
(tests/test_odometry_batch.py holds the two together); the Python classes stay the reference and
what a robot given its own `estimators=` runs. Parameters are read from reset Python estimators,
so every formula for them (tolerances, believed geometry) has one home, `bots.odometry`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numba
import numpy as np

from bots.odometry import TURN_MEMORY, TURN_SCALE_ERROR, default_estimators
from bots.spec import RobotSpec
from sim.kinematics.batch import advance_one

# the estimates of one robot (n, ESTIMATES, 3): the order of `default_estimators`
ENCODERS, FIRMWARE, MOUSE, FUSED, ESTIMATES = 0, 1, 2, 3, 4
# per-robot parameters (n, PARAMS) float64: metres of rim per tick (left, right), believed track
# (m), mouse counts per metre, mouse mount x, y (m), the fused estimator's tolerance (m) and turn
# tolerance (rad), TURN_MEMORY and TURN_SCALE_ERROR (passed, not compiled in: numba's cache of this
# module would not see them change in bots.odometry), and whether the robot has the mouse
# estimators (1.0) or only the encoders' (0.0)
TICK_LEFT, TICK_RIGHT, TRACK, PER_METRE, MOUNT_X, MOUNT_Y, TOLERANCE, TURN_TOLERANCE, MEMORY, SCALE_ERROR, HAS_MOUSE, PARAMS = range(12)
# the fused estimator's state (n, STATE) float64, as `FusedOdometry`'s attributes of those names;
# TIME is nan before the first step (FusedOdometry.time None)
DISAGREEMENT, TURN_DISAGREEMENT, TAKEN, TURNING, TIME, STATE = range(6)


def batched(robot: RobotSpec) -> bool:
    """Whether `DefaultOdometry` steps this robot's default estimators (a general chassis's are
    `bots.chassis_odometry`'s, stepped in Python)."""
    return robot.chassis is None


class DefaultOdometry:
    """The default estimators of several robots (each `batched`), reset at their start poses.

    `poses` (n, ESTIMATES, 3) holds each robot's estimates, updated in place by `update`; a robot
    without a mouse that sees rotation has only the first two (`names`). `contact_steps` (n,)
    counts each fused estimator's steps of wall contact, as `FusedOdometry.contact_steps`."""

    def __init__(self, robots: Sequence[RobotSpec], poses: np.ndarray, rows: Sequence[int]):
        """`poses` (n, 3) the start poses; `rows` each robot's row in the tallies `update` gets."""
        n = len(robots)
        self.rows = np.array(rows, dtype=np.int64).reshape(n)
        self.params = np.zeros((n, PARAMS))
        self.state = np.zeros((n, STATE))
        self.state[:, TIME] = math.nan
        self.contact_steps = np.zeros(n, dtype=np.int64)
        self.poses = np.repeat(np.asarray(poses, dtype=np.float64).reshape(n, 1, 3), ESTIMATES, axis=1)
        self.names: list[list[str]] = []
        for k, (robot, pose) in enumerate(zip(robots, self.poses[:, 0])):
            chosen = default_estimators(robot)
            for estimator in chosen:
                estimator.reset(robot, pose)
            self.names.append([estimator.name for estimator in chosen])
            p = self.params[k]
            encoders = chosen[ENCODERS]
            p[TICK_LEFT], p[TICK_RIGHT] = encoders.metres_per_tick
            p[TRACK] = encoders.track
            if len(chosen) > MOUSE:
                mouse, fused = chosen[MOUSE], chosen[FUSED]
                p[PER_METRE], (p[MOUNT_X], p[MOUNT_Y]) = mouse.per_metre, mouse.mount
                p[TOLERANCE], p[TURN_TOLERANCE] = fused.tolerance, fused.turn_tolerance
                p[MEMORY], p[SCALE_ERROR] = TURN_MEMORY, TURN_SCALE_ERROR
                p[HAS_MOUSE] = 1.0
        self._out = np.zeros((n, 1 + ESTIMATES, 3))  # (where `update` is not given a run's row)
        self._truth = np.zeros((max(self.rows.max(initial=-1) + 1, 0), 3))
        # the kernel for these arrays' types, called without numba's dispatch (a third of its cost),
        # as `sim.world.compiling.compiled_for` does it for the world (bots/ does not import the world)
        arguments = (np.zeros((1, 4), np.int64), self.rows, 0.0, self.params, self.state, self.contact_steps, self.poses, self._truth, self._out)
        self._step = _step.compile(tuple(_step.typeof_pyval(argument) for argument in arguments))

    def rows_of(self, k: int) -> np.ndarray:
        """The `k`-th robot's estimates, (estimates, 3), a view into `poses` in the order of
        `names[k]` (valid for the batch's life: `update` writes in place)."""
        return self.poses[k, : len(self.names[k])]

    def update(self, tallies: np.ndarray, time: float, truth: np.ndarray | None = None, out: np.ndarray | None = None) -> None:
        """Step every robot's estimates by one step's readings: `tallies` (rows, 4) int64 encoder
        ticks (left, right) then mouse counts (forward, left) per robot (`SensorFrame.tallies`), read
        at `time` (s). With `out` (n, 1 + ESTIMATES, 3), a run's sample row, each robot's true pose
        (its row of `truth`, (rows, 3)) and estimates are written there too, in the same pass."""
        tallies = np.ascontiguousarray(tallies, dtype=np.int64)  # (the types `_step` was compiled for)
        if out is None:
            truth, out = self._truth, self._out
        else:
            truth, out = np.ascontiguousarray(truth, dtype=np.float64), np.ascontiguousarray(out, dtype=np.float64)
        self.update_into(tallies, float(time), truth, out)

    def update_into(self, tallies: np.ndarray, time: float, truth: np.ndarray, out: np.ndarray) -> None:
        """`update` with `out`, for a caller whose arrays already have the types the kernel was
        compiled for (C-ordered: int64 tallies, float64 truth and out; a float time), as a run's
        columns do: no conversions, which would cost as much as the kernel's work."""
        self._step(tallies, self.rows, time, self.params, self.state, self.contact_steps, self.poses, truth, out)


@numba.njit(cache=True, inline="always")
def _lay(pose: np.ndarray, s: float, alpha: float, end_heading: bool) -> None:
    """`_ArcOdometry.update`: the pose after the arc, in place."""
    pose[0], pose[1], pose[2] = advance_one(pose[0], pose[1], pose[2], s, alpha, end_heading)


@numba.njit(cache=True, inline="always")
def _clip(value: float, bound: float) -> float:
    """min(max(value, -bound), bound) with Python's choice on ties (the first argument)."""
    if -bound > value:
        value = -bound
    return bound if bound < value else value


@numba.njit(cache=True)
def _step(
    tallies: np.ndarray, rows: np.ndarray, time: float, params: np.ndarray, state: np.ndarray, contact_steps: np.ndarray,
    poses: np.ndarray, truth: np.ndarray, out: np.ndarray,
) -> None:
    """One step of every robot's default estimators, in place: the arcs of `EncoderOdometry.arc`
    and `MouseOdometry.arc`, the slip rule of `FusedOdometry.arc` and `_rotation`, laid down as
    `_ArcOdometry.update` lays them (`advance_one`). Each line keeps the Python expression's order.
    Where `out` has rows: out[i] = the true pose, then the estimates (a run's log, one pass)."""
    if out.shape[0] != rows.shape[0]:
        raise ValueError("DefaultOdometry.update: out must have a row for every robot of the batch")
    for i in range(rows.shape[0]):
        r, p, st, pose = rows[i], params[i], state[i], poses[i]
        if r >= tallies.shape[0] or tallies.shape[1] != 4:  # a kernel reads past an array's end without a word
            raise ValueError("DefaultOdometry.update: tallies must be (robots, 4) with a row for every robot of the batch")
        s_left, s_right = tallies[r, 0] * p[TICK_LEFT], tallies[r, 1] * p[TICK_RIGHT]
        s_enc, alpha_enc = 0.5 * (s_left + s_right), (s_right - s_left) / p[TRACK]
        _lay(pose[ENCODERS], s_enc, alpha_enc, False)
        _lay(pose[FIRMWARE], s_enc, alpha_enc, True)
        if p[HAS_MOUSE] == 0.0:
            continue
        alpha_mouse = tallies[r, 3] / p[PER_METRE] / p[MOUNT_X]
        s_mouse = tallies[r, 2] / p[PER_METRE] + alpha_mouse * p[MOUNT_Y]
        _lay(pose[MOUSE], s_mouse, alpha_mouse, False)
        # FusedOdometry.arc: distance from the encoders within `tolerance` of the mouse's
        total = st[DISAGREEMENT] + s_enc - s_mouse
        st[DISAGREEMENT] = _clip(total, p[TOLERANCE])
        s_fused = s_enc - (total - st[DISAGREEMENT])
        # FusedOdometry._rotation: the mouse's rotation unless it slides (wall contact)
        if math.isnan(st[TIME]):
            keep = 1.0
        else:
            elapsed = time - st[TIME]
            keep = math.exp(-(0.0 if 0.0 > elapsed else elapsed) / p[MEMORY])
        st[TIME] = time
        st[TURNING] = st[TURNING] * keep + abs(alpha_enc)
        st[TURN_DISAGREEMENT] = st[TURN_DISAGREEMENT] * keep + alpha_mouse - alpha_enc
        st[TAKEN] = st[TAKEN] * keep
        if abs(st[TURN_DISAGREEMENT]) <= p[TURN_TOLERANCE] + p[SCALE_ERROR] * st[TURNING]:
            st[TAKEN] += alpha_mouse - alpha_enc
            alpha_fused = alpha_mouse
        else:
            contact_steps[i] += 1
            alpha_fused = alpha_enc - st[TAKEN]
            st[TAKEN] = 0.0
        _lay(pose[FUSED], s_fused, alpha_fused, False)
    for i in range(out.shape[0]):
        if rows[i] >= truth.shape[0]:
            raise ValueError("DefaultOdometry.update: truth must have a row for every robot of the batch")
        out[i, 0] = truth[rows[i]]
        out[i, 1:] = poses[i]
