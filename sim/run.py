"""The run loop: the one place that holds both ground truth and what the robots believe.

Per step, in the order of DESIGN.md §4: every robot's sensors are read from the state at the start
of the step, its odometry estimators take the readings, its controller turns them into a command,
the kinematics core turns the command into motor commands, and the world advances. Observers
(recording, progress bars) see every step; a controller that raises ends the run with a message
naming it and the step, and everything up to that step is kept.
"""

from __future__ import annotations

import math
import traceback
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from bots.commands import BadCommand, motor_commands, wheel_speeds_for
from bots.controller import Controller, reset
from bots.odometry import Estimator, default_estimators
from bots.spec import RobotSpec
from sim.world import World
from sim.world.readings import Readings
from sim.world.spec import Start, WorldSpec


@dataclass
class RobotSetup:
    """A robot to put in the world: its description, its controller and optionally its start."""

    spec: RobotSpec
    controller: Controller
    controller_name: str = "controller"
    params: dict[str, str] = field(default_factory=dict)
    start: Start | tuple[float, float, float] | None = None
    estimators: list[Estimator] | None = None


@dataclass
class RobotLog:
    """Everything one robot did in a run, one row per sample (the start of every step, and the
    end of the run): ground truth, each estimate, its readings and commands."""

    name: str
    spec: RobotSpec
    controller_name: str
    params: dict[str, str]
    truth: list[np.ndarray] = field(default_factory=list)
    estimates: dict[str, list[np.ndarray]] = field(default_factory=dict)
    readings: list[Readings] = field(default_factory=list)
    wheel_speeds: list[tuple[float, float]] = field(default_factory=list)
    collisions: int = 0
    fell: bool = False
    goal_time: float | None = None

    @property
    def latest(self) -> Readings | None:
        """The readings of the current sample (None before the first)."""
        return self.readings[-1] if self.readings else None

    def truth_array(self) -> np.ndarray:
        """(T, 3) ground-truth poses."""
        return np.array(self.truth).reshape(-1, 3)

    def estimate_arrays(self) -> dict[str, np.ndarray]:
        """Estimator name -> (T, 3) estimated poses."""
        return {name: np.array(poses).reshape(-1, 3) for name, poses in self.estimates.items()}


@dataclass
class RunResult:
    """A finished (or stopped) run. `reason` is 'duration', 'goal', 'error' or 'interrupted';
    `error` holds the one-line message of a failure."""

    world: WorldSpec
    seed: int
    dt: float
    times: list[float]
    robots: list[RobotLog]
    reason: str = "duration"
    error: str | None = None

    @property
    def time(self) -> np.ndarray:
        """(T,) sample times (s)."""
        return np.asarray(self.times)


class Observer(Protocol):
    """Sees a run go by (recorders, progress bars); every method is optional."""

    def on_start(self, world: World, logs: list[RobotLog]) -> None: ...
    def on_sample(self, world: World, logs: list[RobotLog]) -> None: ...
    def on_end(self, result: RunResult) -> None: ...


class RunError(RuntimeError):
    """A run that could not start (bad setup); the message is for the user."""


def _notify(observers, method: str, *args) -> None:
    for observer in observers:
        handler = getattr(observer, method, None)
        if handler is not None:
            handler(*args)


def _in_goal(world: WorldSpec, pose: np.ndarray) -> bool:
    for goal in world.goals:
        v = np.asarray(goal.vertices)
        edges = np.roll(v, -1, axis=0) - v
        rel = pose[:2] - v
        cross = edges[:, 0] * rel[:, 1] - edges[:, 1] * rel[:, 0]
        if np.all(cross >= 0) or np.all(cross <= 0):
            return True
    return False


def run(
    world_spec: WorldSpec,
    robots: list[RobotSetup],
    duration: float,
    dt: float = 0.01,
    seed: int = 0,
    until_goal: bool = False,
    observers: tuple = (),
) -> RunResult:
    """Simulate `robots` in `world_spec` for `duration` seconds (or until one reaches a goal)."""
    if not (math.isfinite(duration) and duration >= 0):
        raise RunError(f"duration must be a non-negative number of seconds, got {duration!r}")
    world = World(world_spec, dt=dt, seed=seed)
    logs, controllers, estimators = [], [], []
    for setup in robots:
        robot = world.add_robot(setup.spec, setup.start)
        pose = robot.pose
        chosen = setup.estimators if setup.estimators is not None else default_estimators(setup.spec)
        for estimator in chosen:
            estimator.reset(setup.spec, pose)
        reset(setup.controller, setup.spec)
        logs.append(RobotLog(robot.name, setup.spec, setup.controller_name, dict(setup.params), estimates={e.name: [] for e in chosen}))
        controllers.append(setup.controller)
        estimators.append(chosen)
    result = RunResult(world_spec, seed, dt, [], logs)
    steps = int(round(duration / dt))
    commands = np.zeros((len(robots), 2))
    _notify(observers, "on_start", world, logs)
    try:
        for step in range(steps + 1):
            _sample(world, logs, estimators, result)
            _notify(observers, "on_sample", world, logs)
            if until_goal and any(log.goal_time is not None for log in logs):
                result.reason = "goal"
                break
            if step == steps:
                break
            for i, (robot, log, controller) in enumerate(zip(world.robots, logs, controllers)):
                readings = log.readings[-1]
                try:
                    command = controller.step(world.time, readings)
                    left, right = wheel_speeds_for(command, robot.spec)
                except BadCommand as err:
                    raise _Stop(f"controller {log.controller_name!r} of {log.name} returned a bad command at step {step} (t = {world.time:.2f} s): {err}") from None
                except Exception as err:  # the controller's own bug: stop, keep what we have
                    where = _last_frame(err)
                    raise _Stop(
                        f"controller {log.controller_name!r} of {log.name} raised {type(err).__name__}: {err} "
                        f"at step {step} (t = {world.time:.2f} s){where}"
                    ) from None
                log.wheel_speeds.append((left, right))
                commands[i] = motor_commands(left, right, robot.spec)
            world.step(commands)
    except _Stop as stop:
        result.reason, result.error = "error", str(stop)
    except KeyboardInterrupt:
        result.reason, result.error = "interrupted", f"interrupted at t = {world.time:.2f} s"
    finally:
        _complete_samples(result)
        for robot, log in zip(world.robots, logs):
            log.collisions, log.fell = robot.collisions, robot.fallen
        _notify(observers, "on_end", result)
    return result


class _Stop(Exception):
    pass


def _last_frame(err: BaseException) -> str:
    frames = traceback.extract_tb(err.__traceback__)
    return f" ({frames[-1].filename}:{frames[-1].lineno})" if frames else ""


def _complete_samples(result: RunResult) -> None:
    """Drop a sample that Ctrl-C cut in half (its time logged, some robot's poses not yet), so
    that every trajectory has one pose per time."""
    lists = [result.times] + [x for log in result.robots for x in (log.truth, log.readings, *log.estimates.values())]
    n = min(len(x) for x in lists)
    for x in lists:
        del x[n:]


def _sample(world: World, logs: list[RobotLog], estimators: list[list[Estimator]], result: RunResult) -> None:
    """Read every robot's sensors at the current state and log truth and estimates."""
    result.times.append(world.time)
    for robot, log, chosen, readings in zip(world.robots, logs, estimators, world.read_all()):
        pose = robot.pose
        log.readings.append(readings)
        log.truth.append(pose)
        for estimator in chosen:
            estimator.update(readings)
            log.estimates.setdefault(estimator.name, []).append(estimator.pose.copy())
        if log.goal_time is None and _in_goal(world.spec, pose):
            log.goal_time = world.time
