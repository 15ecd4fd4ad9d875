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
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from bots.chassis_commands import chassis_setpoints
from bots.commands import BadCommand, motor_commands, wheel_speeds_for
from bots.controller import Controller, ControllerStopped, Status, reset
from bots.odometry.base import Estimator
from bots.odometry.batch import DefaultOdometry, batched
from bots.odometry.defaults import default_estimators
from bots.odometry.user import check, name_of
from bots.readings import Readings, SensorFrame
from bots.spec import RobotSpec
from sim.guards import ControllerBrokeOut, Guard
from sim.run.clock import StepClock, StepTimeout
from sim.run.ending import Ending, Quit, RunError, Terminated
from sim.run.samples import RobotLog, RunResult, Samples
from sim.world import World
from sim.world.chassis_drive import FaultError
from sim.world.spec import Start, WheelFault, WorldSpec
from sim.world.step import DEFAULT_DT, StepError, check_dt


@dataclass
class RobotSetup:
    """A robot to put in the world: its description, its controller and optionally its start."""

    spec: RobotSpec
    controller: Controller
    controller_name: str = "controller"
    params: dict[str, str] = field(default_factory=dict)
    start: Start | tuple[float, float, float] | None = None
    estimators: list[Estimator] | None = None
    faults: tuple[WheelFault, ...] = ()
    """Wheel faults of this robot (a general chassis) scheduled by its environment; `robot` is ignored."""
    name: str | None = None
    """The robot's name in logs and recordings (default: its spec's name, numbered after the first)."""
    noise: str | None = None
    """The noise preset its spec was made with (`bots.noise`), for the run's summary (None: not said)."""


class Observer(Protocol):
    """Sees a run go by (recorders, progress bars); every method is optional."""

    def on_start(self, world: World, logs: list[RobotLog]) -> None: ...
    def on_sample(self, world: World, logs: list[RobotLog]) -> None: ...
    def on_end(self, result: RunResult) -> None: ...


MAX_DURATION = 1e7
"""Longest run (simulated s, about 116 days): the sweep spec's limit too."""


def _notify(observers, method: str, *args) -> None:
    for observer in observers:
        handler = getattr(observer, method, None)
        if handler is not None:
            handler(*args)


def run(
    world_spec: WorldSpec,
    robots: list[RobotSetup],
    duration: float,
    dt: float = DEFAULT_DT,
    seed: int = 0,
    until_goal: bool = False,
    observers: tuple = (),
    step_timeout: float | None = None,
    stop_when: Callable[[World, list[RobotLog]], str | None] | None = None,
) -> RunResult:
    """Simulate `robots` in `world_spec` for `duration` seconds (or until one reaches a goal).
    A controller step that takes longer than `step_timeout` seconds (wall clock; None: no limit)
    ends the run as a controller error (`StepClock`). `stop_when(world, logs)`, asked after every
    sample (a referee), ends the run when it answers something: reason JUDGED, its answer the result's `verdict`."""
    steps = step_count(duration, dt)
    world = World(world_spec, dt=dt, seed=seed)
    placed = [world.add_robot(setup.spec, setup.start, setup.name) for setup in robots]
    _refuse_overlaps(placed)
    # the default estimators of all robots that use them are stepped together, in one compiled pass
    members = [i for i, setup in enumerate(robots) if setup.estimators is None and batched(setup.spec)]
    odometry = DefaultOdometry([robots[i].spec for i in members], np.array([placed[i].pose for i in members]).reshape(-1, 3), members) if members else None
    slot = {i: k for k, i in enumerate(members)}
    samples = Samples(world.sensor_rows(), len(members), steps + 1)
    logs, controllers, estimators = [], [], []
    for i, (setup, robot) in enumerate(zip(robots, placed)):
        if i in slot:  # no Python estimators: the batch logs its rows
            names = odometry.names[slot[i]]
        else:
            chosen = setup.estimators if setup.estimators is not None else default_estimators(setup.spec)
            for estimator in chosen:
                try:
                    estimator.reset(setup.spec, robot.pose)
                except Exception as err:  # a user's estimator that cannot take this robot: the user's choice
                    raise RunError(f"{robot.name}: estimator {name_of(estimator)!r} could not be reset: {type(err).__name__}: {err}{_last_frame(err)}") from None
            names = [estimator.name for estimator in chosen]
        try:
            reset(setup.controller, setup.spec)
        except ValueError as err:  # a controller that cannot drive this robot (too few sensors): the user's choice
            raise RunError(f"{robot.name}: {err}") from None
        uncertain = None if i in slot else [e.name for e in chosen if _has_covariance(e)]
        log = RobotLog(robot.name, setup.spec, setup.controller_name, dict(setup.params), names, samples, i, world, slot.get(i), uncertain)
        log.noise = setup.noise
        logs.append(log)
        controllers.append(setup.controller)
        if i not in slot:
            estimators.append((i, log, chosen))
    try:
        world.chassis.schedule_faults([*world_spec.faults, *(replace(f, robot=i) for i, setup in enumerate(robots) for f in setup.faults)])
    except FaultError as err:
        raise RunError(str(err)) from None
    result = RunResult(world_spec, seed, dt, logs, samples)
    commands = np.zeros((len(robots), 2))
    clock = StepClock(step_timeout)
    call = 0
    guard: Guard | None = None
    try:
        clock.__enter__()
        guard = Guard().__enter__()
        _notify(observers, "on_start", world, logs)  # inside: Ctrl-C while a recorder opens still ends the run
        samplers = [observer.on_sample for observer in observers if hasattr(observer, "on_sample")]
        drivers = [(i, robot.spec, log, controller) for i, (robot, log, controller) in enumerate(zip(world.robots, logs, controllers))]
        can_finish = all(hasattr(controller, "status") for controller in controllers)  # a behaviour says when it is done
        for step in range(steps + 1):
            frame = _sample(world, samples, logs, estimators, odometry)
            for on_sample in samplers:
                on_sample(world, logs)
            if until_goal and any(log.goal_time is not None for log in logs):
                result.reason = Ending.GOAL
                break
            if can_finish and not any(controller.status is Status.RUNNING for controller in controllers):
                result.reason = Ending.DONE
                break
            if stop_when is not None and (verdict := stop_when(world, logs)):
                result.reason, result.verdict = Ending.JUDGED, str(verdict)
                break
            if step == steps:
                break
            now = world.time
            for i, spec, log, controller in drivers:
                readings = frame[i]
                try:
                    call += 1
                    clock.busy = call
                    command = controller.step(now, readings)
                    clock.busy = 0
                    if spec.chassis is not None:
                        _drive_chassis(world, i, log, command, readings, step)
                        continue
                    left, right = wheel_speeds_for(command, spec)
                except KeyboardInterrupt:  # Ctrl-C or SIGTERM, not the controller's doing
                    raise
                except BaseException as err:  # the controller's error: anything it raises, sys.exit and a step timeout too
                    clock.busy = 0
                    raise _Stop(_failure(err, log, step, world.time, step_timeout)) from None
                commands[i] = motor_commands(left, right, spec)
            guard.after_step(step)
            world.step(commands)
    except _Stop as stop:
        result.reason, result.error = Ending.ERROR, str(stop)
    except ControllerBrokeOut as broke:
        result.reason, result.error = Ending.ERROR, f"{_who(logs)} {broke} at step {step} (t = {world.time:.2f} s)"
    except Exception as err:  # ctsim's own code failing: a ctsim bug, unless a controller replaced what it calls
        replaced = guard.replaced() if guard is not None else ""
        if not replaced:
            raise
        result.reason = Ending.ERROR
        result.error = f"{_who(logs)} replaced {replaced}, and the run failed with {type(err).__name__}: {err} at t = {world.time:.2f} s"
    except KeyboardInterrupt as stop:
        clock.busy = 0
        result.reason = Ending.QUIT if isinstance(stop, Quit) else Ending.TERMINATED if isinstance(stop, Terminated) else Ending.INTERRUPTED
        result.error = None if result.reason is Ending.QUIT else f"{result.reason} at t = {world.time:.2f} s"
    finally:
        clock.__exit__()
        if guard is not None:
            guard.__exit__()
            result.notes = list(guard.notes.values())
        for robot, log, controller in zip(world.robots, logs, controllers):
            log.collisions, log.fell = robot.collisions, robot.fallen
            log.status = controller.status.value if isinstance(getattr(controller, "status", None), Status) else None
        _notify(observers, "on_end", result)
    return result


class _Stop(Exception):
    pass


def _who(logs: list[RobotLog]) -> str:
    """The controller(s) of a run, for a line about what one of them did."""
    if len(logs) == 1:
        return f"controller {logs[0].controller_name!r} of {logs[0].name}"
    return f"a controller (of {', '.join(log.name for log in logs[:5])}{', ...' if len(logs) > 5 else ''})"


def _failure(err: BaseException, log: RobotLog, step: int, time: float, step_timeout: float | None) -> str:
    """The one line that says how a robot's controller ended the run."""
    when = f"at step {step} (t = {time:.2f} s)"
    if isinstance(err, BadCommand):
        return f"controller {log.controller_name!r} of {log.name} returned a bad command {when}: {err}"
    if isinstance(err, ControllerStopped):
        return f"{log.name} ({log.controller_name}) stopped {when}: {err}"
    if isinstance(err, StepTimeout):
        return f"controller {log.controller_name!r} of {log.name} took longer than the step time limit of {step_timeout:g} s {when}"
    return f"controller {log.controller_name!r} of {log.name} raised {type(err).__name__}: {err} {when}{_last_frame(err)}"


def step_count(duration: float, dt: float) -> int:
    """The number of steps of a run, or RunError for a request the physics cannot hold."""
    try:
        check_dt(dt)
    except StepError as err:
        raise RunError(str(err)) from None
    if isinstance(duration, bool) or not isinstance(duration, (int, float)) or not (math.isfinite(duration) and duration >= 0):
        raise RunError(f"duration must be a non-negative number of seconds, got {duration!r}")
    if duration > MAX_DURATION:
        raise RunError(f"a duration of {duration:g} s is more than the {MAX_DURATION:g} s (about 116 days) a run may have")
    steps = int(round(duration / dt))
    if steps == 0 and duration > 0:
        raise RunError(f"a duration of {duration:g} s is less than half a step (dt = {dt:g} s): nothing would be simulated")
    return steps


def _refuse_overlaps(robots: list) -> None:
    """RunError when two robots start with their bodies overlapping: the contact solver would push
    them apart at once, possibly through a wall. Robots are binned into cells as wide as the
    largest body, so each is compared with its neighbours only."""
    if len(robots) < 2:
        return
    radii = [robot.spec.body_radius for robot in robots]
    cell = 2 * max(radii)
    bins: dict[tuple[int, int], list[int]] = {}
    for j, robot in enumerate(robots):
        x, y = robot.pose[0], robot.pose[1]
        key = (math.floor(x / cell), math.floor(y / cell))
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for i in bins.get((key[0] + dx, key[1] + dy), ()):
                    gap = math.hypot(x - robots[i].pose[0], y - robots[i].pose[1])
                    if gap < (radii[i] + radii[j]) * (1 - 1e-9):  # touching is allowed (rounding of a shared edge)
                        raise RunError(
                            f"{robots[i].name} and {robot.name} start {gap:.3f} m apart, closer than their bodies allow "
                            f"({radii[i] + radii[j]:.3f} m): give them starts farther apart"
                        )
        bins.setdefault(key, []).append(j)


def _drive_chassis(world: World, index: int, log: RobotLog, command, readings: Readings, step: int) -> None:
    """Turn a chassis robot's command into wheel set-points (the core's inverse kinematics) for the world."""
    setpoint = chassis_setpoints(command, log.spec, readings)
    if setpoint.note:
        log.note(f"step {step} (t = {world.time:.2f} s): {setpoint.note}")
    world.chassis.command(index, setpoint.phi_dot, setpoint.beta)


def _last_frame(err: BaseException) -> str:
    frames = traceback.extract_tb(err.__traceback__)
    return f" ({frames[-1].filename}:{frames[-1].lineno})" if frames else ""


def _update(estimator: Estimator, readings: Readings, log: RobotLog, step: int) -> None:
    """Step an estimator; one that raises or leaves a bad pose or covariance ends the run (_Stop),
    as a controller's error does."""
    try:
        estimator.update(readings)
        problem = check(estimator)
    except KeyboardInterrupt:
        raise
    except BaseException as err:  # the estimator's error (a user's code; sys.exit too)
        raise _Stop(f"estimator {name_of(estimator)!r} of {log.name} raised {type(err).__name__}: {err} at step {step} (t = {readings.time:.2f} s){_last_frame(err)}") from None
    if problem is not None:
        raise _Stop(f"estimator {name_of(estimator)!r} of {log.name} failed at step {step} (t = {readings.time:.2f} s): {problem}")


def _has_covariance(estimator: Estimator) -> bool:
    """Whether an estimator reports a covariance (the Protocol's optional `covariance`)."""
    return hasattr(type(estimator), "covariance") or hasattr(estimator, "covariance")


def _sample(
    world: World, samples: Samples, logs: list[RobotLog], estimators: list[tuple[int, RobotLog, list[Estimator]]],
    odometry: DefaultOdometry | None,
) -> SensorFrame:
    """Read every robot's sensors at the current state into the run's next sample row and log
    truth and estimates: the default odometry of all batched robots updates and logs them in one
    pass; robots with Python estimators update theirs here. Then note who reached a goal."""
    n = samples.count
    time = world.time
    frame = samples.frame = world.read_all((samples.values[n], samples.believed[n], samples.tallies[n]))
    for array in (frame.tallies, frame.ir_raw, frame.ir_distance, frame.floor, frame.light):
        array.flags.writeable = False  # (views of the run's recorded rows: a controller must not rewrite them)
    samples.time[n] = time
    poses = world.poses()
    if odometry is not None:
        odometry.update_into(frame.tallies, time, poses, samples.poses[n], samples.covariances[n])
    for i, log, chosen in estimators:
        readings = frame[i]
        for estimator in chosen:
            _update(estimator, readings, log, n)
        log.append(poses[i], [estimator.pose for estimator in chosen], [estimator.covariance for estimator in chosen if _has_covariance(estimator)])
    samples.count = n + 1
    samples.columns.release_written(n + 1)
    goals = world.spec.goals
    if goals:
        for (x, y), log, robot in zip(poses[:, :2].tolist(), logs, world.robots):
            if log.goal_time is None and world.spec.in_goal(x, y, robot.slot):
                log.goal_time = time
    return frame
