"""The run loop: the one place that holds both ground truth and what the robots believe.

Per step, in the order of DESIGN.md §4: every robot's sensors are read from the state at the start
of the step, its odometry estimators take the readings, its controller turns them into a command,
the kinematics core turns the command into motor commands, and the world advances. Observers
(recording, progress bars) see every step; a controller that raises ends the run with a message
naming it and the step, and everything up to that step is kept.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from bots.chassis_commands import chassis_setpoints
from bots.commands import BadCommand, command_per_speed, wheel_speeds_for
from bots.controller import Controller, ControllerStopped, Status, did, reset, where
from bots.odometry.base import Estimator
from bots.odometry.batch import DefaultOdometry, batched, kernel_jobs
from bots.odometry.defaults import default_estimators
from bots.odometry.user import has_covariance, name_of, outputs
from bots.readings import Readings, SensorFrame
from bots.spec import RobotSpec
from sim.guards import ControllerBrokeOut, Guard, foreign_frame, user_code_folders
from sim.interrupts import Counting
from sim.run.clock import StepClock, StepTimeout
from sim.run.ending import Ending, Quit, RunError, Terminated
from sim.run.samples import RobotLog, RunResult, Samples, SamplesNotKept
from sim.world import World, compiling
from sim.world.chassis_drive import FaultError
from sim.world.localising import MapScan
from sim.world.physics import Robot, sensor_rng
from sim.world.spec import Goal, Start, WheelFault, WorldSpec
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
    """Estimators in place of the robot's defaults (None: the defaults)."""
    extra_estimators: list[Estimator] = field(default_factory=list)
    """A user's own estimators beside the estimators above (the defaults stay in their compiled pass)."""
    faults: tuple[WheelFault, ...] = ()
    """Wheel faults of this robot (a general chassis) scheduled by its environment; `robot` is ignored."""
    name: str | None = None
    """The robot's name in logs and recordings (default: its spec's name, numbered after the first)."""


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
    check_seed(seed)
    if any(setup.estimators is None and batched(setup.spec) for setup in robots):  # the odometry's compile, where the cache lacks
        compiling.start(kernel_jobs())  # it, beside the world's making (its first kernel compiles here); `DefaultOdometry` waits for it
    world = World(world_spec, dt=dt, seed=seed)
    placed = [world.add_robot(setup.spec, setup.start, setup.name) for setup in robots]
    _refuse_overlaps(placed)
    # the default estimators of all robots that use them are stepped together, in one compiled pass
    members = [i for i, setup in enumerate(robots) if setup.estimators is None and batched(setup.spec)]
    # (its kernel compiles, where numba's cache lacks it, beside the world's: `compiling.start`)
    odometry = DefaultOdometry([robots[i].spec for i in members], np.array([placed[i].pose for i in members]).reshape(-1, 3), members, compiling.start) if members else None
    slot = {i: k for k, i in enumerate(members)}
    samples = Samples(world.sensor_rows(), len(members), steps + 1)
    clock = StepClock(step_timeout)
    counted = Counting()  # (a KeyboardInterrupt user code raises itself is its error, not Ctrl-C)
    guard: Guard | None = None
    try:  # the resets are the run's first user code: timed and guarded as its steps are
        counted.__enter__()
        clock.__enter__()
        guard = Guard().__enter__()
        logs, controllers, estimators, failed = _set_up(world, world_spec, robots, placed, samples, odometry, slot, seed, clock, counted)
        world.chassis.schedule_faults([*world_spec.faults, *(replace(f, robot=i) for i, setup in enumerate(robots) for f in setup.faults)])
    except BaseException as err:
        clock.__exit__()
        if guard is not None:
            guard.__exit__()
        counted.__exit__()
        if isinstance(err, FaultError):
            raise RunError(str(err)) from None
        raise
    result = RunResult(world_spec, seed, dt, logs, samples)
    commands = np.zeros((len(robots), 2))
    statuses: list[Status | None] = [None] * len(controllers)
    try:
        _notify(observers, "on_start", world, logs)  # inside: Ctrl-C while a recorder opens still ends the run
        if failed is not None:
            raise failed
        samplers = [observer.on_sample for observer in observers if hasattr(observer, "on_sample")]
        # per robot what its every step needs, looked up once
        drivers = [(i, robot.spec, log, controller, robot.spec.chassis is not None, command_per_speed(robot.spec))
                   for i, (robot, log, controller) in enumerate(zip(world.robots, logs, controllers))]  # fmt: skip
        running = Status.RUNNING
        awaited = [(log, goals, k, _box_around(goals)) for k, (log, robot) in enumerate(zip(logs, world.robots)) if (goals := world_spec.goals_of(robot.slot))] if world_spec.goals else []
        puts, seen = world.puts, [robot.puts for robot in world.robots]
        for step in range(steps + 1):
            frame = _sample(world, samples, estimators, odometry, clock, guard, counted)
            if world.puts != puts:  # (one number watched per step; the robots' own counts only when it moved)
                puts = _note_puts(world, logs, seen)
            # a behaviour says when it is done: its `status`, read (user code: a property may block) under the step clock as its steps
            if step == 0:
                _statuses(controllers, logs, step, frame.time, clock, counted, step_timeout, statuses, range(len(controllers)))
                told = [i for i, status in enumerate(statuses) if status is not None]
                can_finish = len(told) == len(controllers)
            elif told:
                _statuses(controllers, logs, step, frame.time, clock, counted, step_timeout, statuses, told)
            at_goal = awaited and _reached_goals(awaited, world.poses_view(), frame.time) and until_goal
            if at_goal:
                result.reason = Ending.GOAL
            for on_sample in samplers:
                on_sample(world, logs)
            if at_goal:
                break
            if can_finish and running not in statuses:
                result.reason = Ending.DONE
                break
            if stop_when is not None and (verdict := stop_when(world, logs)):
                result.reason, result.verdict = Ending.JUDGED, str(verdict)
                break
            if step == steps:
                break
            now = frame.time
            readings_of = frame.robots()
            for i, spec, log, controller, on_chassis, per_speed in drivers:
                readings = readings_of[i]
                try:
                    clock.begin()
                    command = controller.step(now, readings)
                    clock.busy = 0
                    if on_chassis:
                        _drive_chassis(world, i, log, command, readings, step)
                        continue
                    left, right = wheel_speeds_for(command, spec)
                except BaseException as err:  # the controller's error: anything it raises, sys.exit and a step timeout too
                    raise _controller_end(err, counted, clock, log, step, world.time, step_timeout) from None
                commands[i, 0] = left * per_speed[0]  # (`motor_commands`, written in place)
                commands[i, 1] = right * per_speed[1]
            guard.after_step(step)
            world.step(commands)
    except _Stop as stop:
        result.reason, result.error, result.failed_estimator = Ending.ERROR, str(stop), stop.estimator
    except SamplesNotKept as lost:  # (the run's file of samples failed it: what it holds is the run's)
        result.reason, result.error = Ending.ERROR, lost.strerror
    except ControllerBrokeOut as broke:
        result.reason, result.error = Ending.ERROR, f"{_who(logs)} {broke} at step {step} (t = {world.time:.2f} s)"
    except Exception as err:  # ctsim's own code failing: a ctsim bug, unless a controller replaced what it calls
        replaced = guard.replaced()
        foreign = foreign_frame(err, user_code_folders([*controllers, *(e for _, _, checked, _ in estimators for e, _, _ in checked)]))
        if not replaced and foreign is None:
            raise
        result.reason = Ending.ERROR
        what = f"replaced {replaced}, and the run" if replaced else f"put its own code into ctsim's ({foreign}), and the run"
        result.error = f"{_who(logs)} {what} failed with {type(err).__name__}: {err} at t = {world.time:.2f} s"
    except KeyboardInterrupt as stop:
        clock.busy = 0
        result.reason = Ending.QUIT if isinstance(stop, Quit) else Ending.TERMINATED if isinstance(stop, Terminated) else Ending.INTERRUPTED
        result.error = None if result.reason is Ending.QUIT else f"{result.reason} at t = {world.time:.2f} s"
    finally:
        clock.__exit__()
        guard.__exit__()
        counted.__exit__()
        result.notes = list(guard.notes.values())
        samples.settle()
        for robot, log, status in zip(world.robots, logs, statuses):
            log.collisions, log.fell = robot.collisions, robot.fallen
            log.status = status.value if status is not None else None  # (as last read: a read now could block past every guard)
        _notify(observers, "on_end", result)
    return result


class _Stop(Exception):
    """The run's end by user code (its one line); `estimator`: (robot index, estimator name) where
    one of a robot's Python estimators ended it."""

    def __init__(self, message: str, estimator: tuple[int, str] | None = None):
        super().__init__(message)
        self.estimator = estimator


_Estimators = tuple[int, RobotLog, list[tuple[Estimator, bool, bool]], Callable | None]
"""A robot's Python estimators in a run: its index, its log, each estimator with whether it has a
covariance and whether it is timed (`_is_timed`), and how the log takes a sample of them beside
the batch's (None: `RobotLog.append`, the robot's own rows)."""


def _set_up(
    world: World, world_spec: WorldSpec, robots: list[RobotSetup], placed: list[Robot], samples: Samples, odometry: DefaultOdometry | None,
    slot: dict[int, int], seed: int, clock: StepClock, counted: Counting,
) -> tuple[list[RobotLog], list[Controller], list[_Estimators], _Stop | None]:
    """Every robot's log, controller and Python estimators (a batched robot's own beside the
    batch's, else all of the robot's), reset (`_reset`); and how a reset failed, if one did (the
    run's error at its start; the robots after it are not reset)."""
    logs, controllers, estimators = [], [], []
    failed: _Stop | None = None
    for i, (setup, robot) in enumerate(zip(robots, placed)):
        chosen = list(setup.extra_estimators) if i in slot else [*(setup.estimators if setup.estimators is not None else default_estimators(setup.spec)), *setup.extra_estimators]
        failed = failed or _reset(setup, robot, chosen, world_spec, seed, i, clock, counted)
        names, uncertain = [name_of(estimator) for estimator in chosen], [name_of(e) for e in chosen if has_covariance(e)]
        if i in slot:  # the batch logs its rows, the robot's own estimators theirs
            log = RobotLog(robot.name, setup.spec, setup.controller_name, dict(setup.params), odometry.names[slot[i]], samples, i, world, slot[i],
                           extra=names, extra_uncertain=uncertain)  # fmt: skip
        else:
            log = RobotLog(robot.name, setup.spec, setup.controller_name, dict(setup.params), names, samples, i, world, None, uncertain)
        logs.append(log)
        controllers.append(setup.controller)
        log.estimators = list(chosen)
        # each estimator with what its steps ask of it every time: whether it has a covariance, whether it is timed
        checked = [(e, has_covariance(e), _is_timed(clock, e)) for e in chosen]
        if i not in slot:  # (it logs its truth with its estimates, even with none)
            estimators.append((i, log, checked, None))
        elif chosen:
            estimators.append((i, log, checked, log.append_extra))
    return logs, controllers, estimators, failed


def _reset(setup: RobotSetup, robot: Robot, chosen: list[Estimator], world_spec: WorldSpec, seed: int, index: int, clock: StepClock,
           counted: Counting) -> _Stop | None:  # fmt: skip
    """Reset a robot's estimators (a localiser first handed its map and a generator of its own)
    and its controller, the user's under the step clock (`_timed`). One that raises a ValueError
    cannot take this robot (a controller with too few sensors): the run is refused (RunError).
    Anything else it raises, sys.exit, a step timeout or a KeyboardInterrupt no signal explains
    (`counted`), is the user's code failing: the end that says so (the run's error at its start,
    every file written), else None."""
    for estimator in chosen:
        what = f"estimator {name_of(estimator)!r} of {robot.name}"
        try:
            with _timed(clock, estimator):
                if hasattr(estimator, "use_map"):  # a localiser: the robot's map of the world (never its pose), a generator of its own
                    estimator.use_map(MapScan(world_spec, setup.spec), sensor_rng(seed, index, f"estimator {name_of(estimator)}"))
                estimator.reset(setup.spec, robot.pose)
        except ValueError as err:
            raise RunError(f"{what} cannot take this robot: {err}{where(err)}") from None
        except BaseException as err:
            if counted.by_signal(err):
                raise
            return _Stop(f"{what} {_ended(err, clock)} in its reset at t = 0.00 s{where(err)}", (index, name_of(estimator)))
    try:
        with _timed(clock, setup.controller):
            reset(setup.controller, setup.spec)
    except ValueError as err:  # a controller that cannot drive this robot (too few sensors): the user's choice
        raise RunError(f"{robot.name}: {err}") from None
    except BaseException as err:
        if counted.by_signal(err):
            raise
        return _Stop(f"controller {setup.controller_name!r} of {robot.name} {_ended(err, clock)} in its reset at t = 0.00 s{where(err)}")
    return None


@contextmanager
def _timed(clock: StepClock | None, code: object) -> Iterator[None]:
    """A call of `code` under the step clock (its time limit; a signal acted on at once), unless
    it is a shipped estimator's (of `bots.odometry`: its first call compiles its kernels) or no
    clock runs."""
    timed = _is_timed(clock, code)
    try:
        if timed:
            clock.begin()
        yield
    finally:
        if timed:
            clock.busy = 0


def _is_timed(clock: StepClock | None, code: object) -> bool:
    """Whether calls of `code` run under the step clock (`_timed`)."""
    return clock is not None and not type(code).__module__.startswith("bots.odometry")


def _ended(err: BaseException, clock: StepClock | None) -> str:
    """What user code did that ended the run: overran the step time limit, left or raised."""
    return f"took longer than the step time limit of {clock.limit:g} s" if isinstance(err, StepTimeout) else did(err)


def _who(logs: list[RobotLog]) -> str:
    """The controller(s) of a run, for a line about what one of them did."""
    if len(logs) == 1:
        return f"controller {logs[0].controller_name!r} of {logs[0].name}"
    return f"a controller (of {', '.join(log.name for log in logs[:5])}{', ...' if len(logs) > 5 else ''})"


def _statuses(controllers: list[Controller], logs: list[RobotLog], step: int, time: float, clock: StepClock, counted: Counting,
              step_timeout: float | None, statuses: list[Status | None], which: Iterable[int]) -> None:
    """Read the `status` of the controllers `which` into `statuses` (None: it has none), in place;
    each read a call of user code under the step clock as a step is, whatever it raises (a
    timeout too) its controller's end of the run (`_Stop`)."""
    for i in which:
        try:
            clock.begin()
            status = getattr(controllers[i], "status", None)
            statuses[i] = status if isinstance(status, Status) else None
            clock.busy = 0
        except BaseException as err:
            raise _controller_end(err, counted, clock, logs[i], step, time, step_timeout, "in its status ") from None


def _controller_end(err: BaseException, counted: Counting, clock: StepClock, log: RobotLog, step: int, time: float, step_timeout: float | None,
                    part: str = "") -> _Stop:  # fmt: skip
    """The end of the run by what a robot's controller raised in a call under the step clock (its
    step, or `part`: its status), the clock stopped; a KeyboardInterrupt a signal explains
    (`counted`: Ctrl-C, SIGTERM) is raised on, not the controller's doing. (Where it failed,
    outside the calls themselves: a guarded call costs no more than the call.)"""
    if counted.by_signal(err):
        raise err
    clock.busy = 0
    return _Stop(_failure(err, log, step, time, step_timeout, part))


def _failure(err: BaseException, log: RobotLog, step: int, time: float, step_timeout: float | None, part: str = "") -> str:
    """The one line that says how a robot's controller ended the run (`part`: where in it, if not its step)."""
    when = f"{part}at step {step} (t = {time:.2f} s)"
    if isinstance(err, BadCommand):
        return f"controller {log.controller_name!r} of {log.name} returned a bad command {when}: {err}"
    if isinstance(err, ControllerStopped):
        return f"{log.name} ({log.controller_name}) stopped {when}: {err}"
    if isinstance(err, StepTimeout):
        return f"controller {log.controller_name!r} of {log.name} took longer than the step time limit of {step_timeout:g} s {when}"
    return f"controller {log.controller_name!r} of {log.name} {did(err)} {when}{where(err)}"


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


def check_seed(seed: object) -> None:
    """RunError naming the argument for a seed that is not a whole number of 0 or more (a float,
    a bool, None: numpy would raise a TypeError, or draw from the operating system's entropy and
    make the run unrepeatable)."""
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise RunError(f"seed must be a whole number of 0 or more (an int), got {seed!r}"[:300])


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


def _update(estimator: Estimator, uncertain: bool, timed: bool, readings: Readings, log: RobotLog, step: int,
            clock: StepClock, counted: Counting) -> tuple[np.ndarray, np.ndarray | None]:  # fmt: skip
    """Step an estimator and read its pose and covariance once (`outputs`; `uncertain`: it has
    one), all of it a call under the step clock as a controller's step is where `timed` (its time
    limit; a signal acted on at once: `_timed`, inline here, as it runs every step); one that
    raises (a KeyboardInterrupt no signal explains too: `counted`), overruns or leaves a bad pose
    or covariance ends the run (_Stop), as a controller's error does. The pose and covariance
    (None without one) as read."""
    try:
        if timed:
            clock.begin()
        estimator.update(readings)
        pose, covariance, problem = outputs(estimator, uncertain)
    except BaseException as err:  # the estimator's error (a user's code; sys.exit and a step timeout too)
        if counted.by_signal(err):
            raise  # Ctrl-C or SIGTERM
        raise _Stop(f"estimator {name_of(estimator)!r} of {log.name} {_ended(err, clock)} at step {step} (t = {readings.time:.2f} s){where(err)}",
                    (log.index, name_of(estimator))) from None
    finally:
        if timed:
            clock.busy = 0
    if problem is not None:
        raise _Stop(f"estimator {name_of(estimator)!r} of {log.name} failed at step {step} (t = {readings.time:.2f} s): {problem}", (log.index, name_of(estimator)))
    return pose, covariance


_ROW = ("poses", "covariances", "values", "believed", "tallies")
"""The columns of a run's sample row `_sample` writes (beside its time)."""


def _sample(world: World, samples: Samples, estimators: list[_Estimators], odometry: DefaultOdometry | None, clock: StepClock, guard: Guard,
            counted: Counting) -> SensorFrame:  # fmt: skip
    """Read every robot's sensors at the current state into the run's next sample row and log
    truth and estimates: the default odometry of all batched robots updates and logs them in one
    pass; Python estimators (a robot's own, or all of a robot outside the batch) update theirs
    here (`_update`; one whose update ended a thread with os._exit ends the run as its error:
    `guard`). The frame holds immutable copies of the row (`World.read_all`): the recorded rows
    themselves never reach a controller."""
    n = samples.count
    at = samples.columns.local(n)
    time = world.time
    poses_row, covariances_row, values, believed, tallies = samples.columns.row(at, _ROW)
    frame = samples.frame = world.read_all((values, believed, tallies))
    samples.columns.arrays["time"][at] = time
    poses = world.poses_view()
    if odometry is not None:
        odometry.update_into(tallies, time, poses, poses_row, covariances_row)
    robots = frame.robots() if estimators else []
    for i, log, checked, beside_batch in estimators:
        readings = robots[i]
        poses_read, covariances = [], []
        for estimator, uncertain, timed in checked:
            pose, covariance = _update(estimator, uncertain, timed, readings, log, n, clock, counted)
            if guard.exited is not None:
                raise _Stop(f"estimator {name_of(estimator)!r} of {log.name} {guard.exited} at step {n} (t = {readings.time:.2f} s)", (i, name_of(estimator)))
            poses_read.append(pose)
            if covariance is not None:
                covariances.append(covariance)
        if beside_batch is None:
            log.append(poses[i], poses_read, covariances)
        else:
            beside_batch(poses_read, covariances)
    samples.count = n + 1
    return frame


def _note_puts(world: World, logs: list[RobotLog], seen: list[int]) -> int:
    """Note the sample just taken in the log of each robot put down since the sample before
    (`RobotLog.puts`; `seen` each robot's count of puts so far, brought up to date); the world's
    count of puts."""
    for i, (robot, log) in enumerate(zip(world.robots, logs)):
        if robot.puts != seen[i]:
            seen[i] = robot.puts
            if len(log) > 1:
                log.puts.append(len(log) - 1)
    return world.puts


def _box_around(goals: tuple[Goal, ...]) -> tuple[float, float, float, float]:
    """The box (xmin, ymin, xmax, ymax) around every one of `goals`' boxes."""
    boxes = [goal.box for goal in goals]
    return min(b[0] for b in boxes), min(b[1] for b in boxes), max(b[2] for b in boxes), max(b[3] for b in boxes)


def _reached_goals(awaited: list[tuple[RobotLog, tuple[Goal, ...], int, tuple[float, float, float, float]]], poses: np.ndarray, time: float) -> bool:
    """Note who of `awaited` (log, its goals, index, the box around them: the robots yet to reach
    a goal) is in one of its goals at `poses`, at `time`, and take them out of it; whether anyone
    was. (A robot outside the box is in none: one comparison a step, not a call per goal.)"""
    reached = False
    for entry in awaited:
        log, goals, k, (xmin, ymin, xmax, ymax) = entry
        x, y, _ = poses[k].tolist()
        if not (xmin <= x <= xmax and ymin <= y <= ymax):
            continue
        for goal in goals:
            if goal.contains(x, y):
                log.goal_time = time
                reached = True
                break
    if reached:
        awaited[:] = [entry for entry in awaited if entry[0].goal_time is None]
    return reached
