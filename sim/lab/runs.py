"""Student code inside a run: an estimator or a controller in the student's process, plugged
into the run loop like the shipped ones, and what the checkers of run-based exercises share.

The run loop calls the proxies once per step; each call is one request to the student's process,
charged to the scenario's time budget. A failure inside the run is kept and raised again after
it (the run loop would otherwise report it as a controller error of its own).
"""

from __future__ import annotations

import numpy as np

from bots.commands import Command, WheelSpeeds
from bots.ctbot import CTBOT
from bots.spec import RobotSpec
from sim.lab.artifacts import observers
from sim.lab.checking import Outcome, fmt
from sim.lab.sandbox import Student, StudentError, command, numbers
from sim.run import RobotSetup, run
from sim.world.readings import Readings
from sim.world.spec import Start, WorldSpec


class RemoteEstimator:
    """The student's estimator class `name` (reset(robot, pose), update(readings), pose)."""

    def __init__(self, student: Student, name: str, label: str = "yours"):
        self.student, self.class_name, self.name = student, name, label
        self.pose = np.zeros(3)

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        self.handle = self.student.new(self.class_name)
        self.student.request("method", (self.handle, "reset", (robot, np.asarray(pose, float).copy()), None), f"{self.class_name}.reset()")
        self.pose = np.asarray(pose, dtype=np.float64).copy()

    def update(self, readings: Readings) -> None:
        what = f"{self.class_name}.update() at t = {readings.time:.2f} s"
        self.pose = numbers(self.student.request("method", (self.handle, "update", (readings,), "pose"), what), (3,), f"{self.class_name}.pose after update()")


class RemoteController:
    """The student's controller class `name`, made with `params` (step(t, readings) -> Command)."""

    def __init__(self, student: Student, name: str, **params):
        self.student, self.class_name, self.params = student, name, params
        self.error: StudentError | None = None

    def reset(self, robot: RobotSpec) -> None:
        self.handle = self.student.new(self.class_name, **self.params)
        self.student.request("method", (self.handle, "reset", (robot,), None), f"{self.class_name}.reset()")

    def step(self, t: float, readings: Readings) -> Command:
        try:
            what = f"{self.class_name}.step() at t = {t:.2f} s"
            return command(self.student.request("step", (self.handle, t, readings), what), what)
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

    def on_sample(self, world, logs) -> None:  # noqa: ANN001
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


def check_estimator(scenario, spec: RobotSpec, student: Student, reference, mistakes: dict) -> Outcome:  # noqa: ANN001
    """An estimator exercise: the student's `Odometry` beside `reference` (an estimator) in a run
    on the scenario's wheel-speed `segments` on an open floor (sampled every `dt` s, default
    0.01), compared over the whole run (the
    scenario's tolerances `position` m and `heading` rad); a failure is matched against
    `mistakes` (hint key -> estimator), each replayed on the same readings."""
    schedule, collect = Schedule(scenario["segments"]), Collect()
    setup = RobotSetup(spec, schedule, "schedule", estimators=[reference, RemoteEstimator(student, "Odometry")])
    result = run(open_floor(), [setup], schedule.duration + 0.5, float(scenario.params.get("dt", 0.01)), scenario.seed, observers=(collect, *observers(scenario)))
    log = result.robots[0]
    expected, yours = log.estimate_arrays()[reference.name], log.estimate_arrays()["yours"]
    tol_p, tol_h = scenario.tolerance["position"], scenario.tolerance["heading"]
    worst = float(np.hypot(*(yours[:, :2] - expected[:, :2]).T).max())
    heading = abs(yours[-1, 2] - expected[-1, 2])
    tracks = {"truth": (result.time, log.truth_array()), "reference": (result.time, expected), "yours": (result.time, yours)}
    tolerance = f"{tol_p:g} m, {tol_h:g} rad"
    if worst <= tol_p and heading <= tol_h:
        return Outcome(fmt(expected[-1]), fmt(yours[-1]), True, tolerance, tracks=tracks)
    start = log.truth_array()[0]
    hint = next((key for key, wrong in mistakes.items()
                 if np.allclose(replay(wrong, spec, start, collect.samples), yours[-1], atol=tol_p, rtol=0)), None)  # fmt: skip
    return Outcome(fmt(expected[-1]), fmt(yours[-1]), False, tolerance, hint, {"error": worst}, tracks=tracks)
