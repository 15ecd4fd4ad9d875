"""Student code inside a run: an estimator or a controller in the student's process, plugged
into the run loop like the shipped ones, and what the checkers of run-based exercises share.

An estimator only watches a run: the run goes first, then the student's estimator is fed its
readings in one request. A controller drives the run: the run loop calls it once per step, one
request each, charged to the scenario's time budget; a failure inside the run is kept and raised
again after it (the run loop would otherwise report it as a controller error of its own).
"""

from __future__ import annotations

import json
import threading
from dataclasses import dataclass

import numpy as np

from bots.commands import Command, WheelSpeeds
from bots.ctbot import CTBOT
from bots.readings import Readings
from bots.spec import RobotSpec
from sim.kinematics import wrap_angle
from sim.lab.artifacts import observers
from sim.lab.checking import Outcome, differing, fmt
from sim.lab.student import Student, StudentError, numbers
from sim.run.loop import RobotSetup, run
from sim.world.spec import Start, WorldSpec
from sim.world.step import DEFAULT_DT


def estimates(student: Student, name: str, robot: RobotSpec, start: np.ndarray, samples: list[Readings]) -> np.ndarray:
    """The student's estimator class `name` (reset(robot, pose), update(readings), pose) fed a
    run's readings as the run loop feeds an estimator, in one request: its pose after each
    update, (T, 3)."""
    handle = student.new(name)
    student.method(handle, "reset", robot, np.asarray(start, dtype=np.float64), what=f"{name}.reset()")
    at = lambda i: f"{name}.update() at t = {samples[i].time:.2f} s"
    poses = student.feed(handle, "update", [(readings,) for readings in samples], "pose", at)
    return numbers(poses, (len(samples), 3), f"{name}.pose after each update()")


class RemoteController:
    """The student's controller class `name`, made with `params` (step(t, readings) -> Command)."""

    def __init__(self, student: Student, name: str, **params):
        self.student, self.class_name, self.params = student, name, params
        self.error: StudentError | None = None

    def reset(self, robot: RobotSpec) -> None:
        self.handle = self.student.new(self.class_name, **self.params)
        self.student.method(self.handle, "reset", robot, what=f"{self.class_name}.reset()")

    def step(self, t: float, readings: Readings) -> Command:
        try:
            return self.student.step(self.handle, t, readings, f"{self.class_name}.step() at t = {t:.2f} s")
        except StudentError as err:
            self.error = err
            raise

    def raise_error(self) -> None:
        """Raise what went wrong inside the run, if anything."""
        if self.error is not None:
            raise self.error


class Schedule:
    """Open-loop wheel speeds: `segments` of (duration s, v_left m/s, v_right m/s), then stop."""

    def __init__(self, segments: list[list[float]]):
        self.ends = np.cumsum([s[0] for s in segments])
        self.speeds = [WheelSpeeds(float(s[1]), float(s[2])) for s in segments]

    def step(self, t: float, readings: Readings) -> Command:
        index = int(np.searchsorted(self.ends, t, side="right"))
        return self.speeds[index] if index < len(self.speeds) else WheelSpeeds(0.0, 0.0)

    @property
    def duration(self) -> float:
        return float(self.ends[-1])


class Collect:
    """Observer keeping every sample's readings of the first robot (to replay them later)."""

    def __init__(self):
        self.samples: list[Readings] = []

    def on_sample(self, world, logs) -> None:
        self.samples.append(logs[0].latest)


def replay(estimator, robot: RobotSpec, start: np.ndarray, samples: list[Readings]) -> np.ndarray:
    """Final pose of `estimator` fed the recorded readings as the run loop feeds it."""
    estimator.reset(robot, start)
    for readings in samples:
        estimator.update(readings)
    return np.asarray(estimator.pose, dtype=np.float64)


def open_floor(size: float = 10.0) -> WorldSpec:
    """A wall-less floor `size` metres across, start at the centre facing +x."""
    half = size / 2
    return WorldSpec("open floor", (-half, -half, half, half), starts=(Start(0.0, 0.0, 0.0),), floor_colour=(1.0, 1.0, 1.0))


def robot(params: dict) -> RobotSpec:
    """The c't-Bot with the scenario's wheel diameter and track (m) where it names them."""
    changes = {k: float(params[k]) for k in ("wheel_diameter", "track_width") if k in params}
    return CTBOT.with_changes(name="labbot", **changes)


def path_distance(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Distance (m) of each of `points` (T, 2) from the polyline `path` (K, 2)."""
    a, b = path[:-1], path[1:]
    ab = b - a
    t = np.clip(np.einsum("tkd,kd->tk", points[:, None] - a, ab) / np.maximum((ab**2).sum(axis=1), 1e-12), 0.0, 1.0)
    closest = a + t[..., None] * ab
    return np.hypot(*(points[:, None] - closest).transpose(2, 0, 1)).min(axis=1)


def moved(truth: np.ndarray, dt: float, seconds: float = 1.0) -> float:
    """Distance (m) between the last pose of `truth` (T, 3) and the one `seconds` before."""
    return float(np.hypot(*(truth[-1, :2] - truth[max(0, len(truth) - 1 - round(seconds / dt)), :2])))


@dataclass(frozen=True)
class _Prepared:
    """What a scenario of an estimator exercise is before any student's code: the run, the
    reference's estimate and each typical mistake's final pose on the same readings."""

    time: np.ndarray
    truth: np.ndarray
    expected: np.ndarray
    samples: list[Readings]
    wrong: dict[str, np.ndarray]


_PREPARED: dict[tuple, _Prepared] = {}
_PREPARED_LOCK = threading.Lock()
PREPARED_KEPT = 64
"""Scenarios kept prepared (a grading's few, for every submission: they share the seed)."""


def _prepare(scenario, spec: RobotSpec, reference, mistakes: dict) -> _Prepared:
    """The scenario's run and replays, made once per grading: every submission graded with the
    same seed gets the same scenarios (kept only without artifacts: those record the run)."""
    key = (scenario.name, scenario.seed, json.dumps(scenario.params, sort_keys=True, default=str), type(reference).__name__, tuple(mistakes))
    if scenario.out is None:
        with _PREPARED_LOCK:
            if key in _PREPARED:
                return _PREPARED[key]
    schedule, collect = Schedule(scenario["segments"]), Collect()
    setup = RobotSetup(spec, schedule, "schedule", estimators=[reference])
    result = run(open_floor(), [setup], schedule.duration + 0.5, float(scenario.params.get("dt", DEFAULT_DT)), scenario.seed, observers=(collect, *observers(scenario)))
    log = result.robots[0]
    truth = log.truth_array()
    wrong = {k: replay(estimator, spec, truth[0], collect.samples) for k, estimator in mistakes.items()}
    prepared = _Prepared(result.time, truth, log.estimate_arrays()[reference.name], collect.samples, wrong)
    if scenario.out is None:
        with _PREPARED_LOCK:
            if len(_PREPARED) >= PREPARED_KEPT:
                _PREPARED.pop(next(iter(_PREPARED)))
            _PREPARED[key] = prepared
    return prepared


def check_estimator(scenario, spec: RobotSpec, student: Student, reference, mistakes: dict) -> Outcome:
    """An estimator exercise: a run on the scenario's wheel-speed `segments` on an open floor
    (sampled every `dt` s, default DEFAULT_DT) with `reference` (an estimator), then the student's
    `Odometry` fed the same readings, compared over the whole run (the scenario's tolerances
    `position` m and `heading` rad, headings wrapped: a wrapped estimate is as right as a
    continuous one). `mistakes` (hint key -> estimator) are each replayed on the same readings;
    those whose final pose is the student's within the tolerance are the row's matches, the
    closest first."""
    prepared = _prepare(scenario, spec, reference, mistakes)
    expected, start = prepared.expected, prepared.truth[0]
    yours = estimates(student, "Odometry", spec, start, prepared.samples)
    tol_p, tol_h = scenario.tolerance["position"], scenario.tolerance["heading"]
    worst = float(np.hypot(*(yours[:, :2] - expected[:, :2]).T).max())
    heading = float(np.abs(wrap_angle(yours[:, 2] - expected[:, 2])).max())
    tracks = {"truth": (prepared.time, prepared.truth), "reference": (prepared.time, expected), "yours": (prepared.time, yours)}
    tolerance = f"{tol_p:g} m, {tol_h:g} rad"
    off = {key: pose_distance(pose, yours[-1]) for key, pose in prepared.wrong.items()}
    matches = tuple(sorted((key for key in off if off[key] <= tol_p), key=off.get))
    if worst <= tol_p and heading <= tol_h:
        return Outcome(fmt(expected[-1]), fmt(yours[-1]), True, tolerance, tracks=tracks, matches=matches)
    return Outcome(*differing(expected[-1], yours[-1]), False, tolerance, None, {"error": worst}, tracks=tracks, matches=matches)


def pose_distance(a: np.ndarray, b: np.ndarray) -> float:
    """The larger of the position distance (m) and the wrapped heading difference (rad) of two poses."""
    return float(max(np.hypot(*(a[:2] - b[:2])), abs(wrap_angle(a[2] - b[2]))))
