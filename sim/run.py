"""The run loop: the one place that holds both ground truth and what the robots believe.

Per step, in the order of DESIGN.md §4: every robot's sensors are read from the state at the start
of the step, its odometry estimators take the readings, its controller turns them into a command,
the kinematics core turns the command into motor commands, and the world advances. Observers
(recording, progress bars) see every step; a controller that raises ends the run with a message
naming it and the step, and everything up to that step is kept.
"""

from __future__ import annotations

import math
import mmap
import os
import re
import signal
import tempfile
import threading
import traceback
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from enum import StrEnum
from typing import Protocol

import numpy as np

from bots.chassis_commands import chassis_setpoints
from bots.commands import BadCommand, motor_commands, wheel_speeds_for
from bots.controller import Controller, ControllerStopped, Status, reset
from bots.odometry.base import Estimator
from bots.odometry.batch import COVARIANCES, ESTIMATES, DefaultOdometry, batched
from bots.odometry.defaults import default_estimators
from bots.odometry.user import check, name_of
from bots.readings import Readings, SensorFrame
from bots.spec import RobotSpec
from sim.errors import UserError
from sim.guards import ControllerBrokeOut, Guard
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


_UPPER = (np.array([0, 0, 0, 1, 1, 2]), np.array([0, 1, 2, 1, 2, 2]))
"""Where a (3, 3) covariance's COVARIANCE_FIELDS entries are."""
BLOCK = 65536
"""Samples per block when a finished run is read through (metrics, files)."""
RESIDENT = 8192
"""Samples of a running log kept in resident memory: observers read the latest ones (the
recorder up to `sim.views.recording.CHUNK` back)."""


def row(shape: tuple[int, ...] = (), kind: type = np.float64) -> np.dtype:
    """The type of one sample's row of a column: `kind` values of `shape` (a numpy subarray dtype)."""
    return np.dtype((kind, shape)) if shape else np.dtype(kind)


class _Columns:
    """Preallocated arrays of a run's samples (name -> the type of one row, `row`), backed by an
    unlinked temporary file instead of anonymous memory. Pages are touched only when written, and
    rows already written or read can be handed back to the operating system (`release`): they stay
    readable (a read brings its page back from the file), so an hour-long run's resident memory
    does not grow with its length, while every column stays an ordinary numpy array."""

    def __init__(self, rows: dict[str, np.dtype], capacity: int):
        page = mmap.PAGESIZE
        sizes = {name: -(-max(capacity, 1) * kind.itemsize // page) * page for name, kind in rows.items()}
        total = max(sum(sizes.values()), page)  # (mmap refuses an empty map)
        with tempfile.TemporaryFile() as handle:
            _reserve(handle.fileno(), total)
            self._map = mmap.mmap(handle.fileno(), total)
        self.arrays: dict[str, np.ndarray] = {}
        self._regions: list[tuple[int, int]] = []  # (byte offset, bytes per row) of each column
        offset = 0
        for name, kind in rows.items():
            count = capacity * math.prod(kind.shape)
            self.arrays[name] = np.frombuffer(self._map, kind.base, count, offset).reshape(capacity, *kind.shape)
            self._regions.append((offset, kind.itemsize))
            offset += sizes[name]
        self._released = 0

    def release(self, start: int, stop: int) -> None:
        """Take rows [start, stop) out of resident memory (whole pages inside that range)."""
        if not hasattr(mmap, "MADV_DONTNEED"):  # not on every platform: memory then just grows
            return
        page = mmap.PAGESIZE
        for offset, width in self._regions:
            first, last = -(-start * width // page) * page, stop * width // page * page
            if last > first:
                self._map.madvise(mmap.MADV_DONTNEED, offset + first, last - first)

    def release_written(self, count: int) -> None:
        """While a run writes: release what lies more than RESIDENT rows behind `count`, once per
        RESIDENT rows."""
        if count - self._released >= 2 * RESIDENT:
            self.release(self._released, count - RESIDENT)
            self._released = count - RESIDENT


def _reserve(descriptor: int, size: int) -> None:
    """Give the columns' file its disk space now: a page first written into a sparse file on a
    full disk kills the process (SIGBUS), a reservation that does not fit is a RunError before
    the run starts, naming the folder (TMPDIR) and what is missing."""
    try:
        if hasattr(os, "posix_fallocate"):
            os.posix_fallocate(descriptor, 0, size)
        else:
            os.truncate(descriptor, size)
    except OSError as err:
        folder = tempfile.gettempdir()
        raise RunError(
            f"the run's trajectories need {size / 1e6:.1f} MB in the temporary folder {folder} and it has no room "
            f"({err.strerror}); free space there or point TMPDIR at a folder with room"
        ) from None


class _Samples:
    """The run's own columns, one row per sample for all robots at once: the sample times, the
    arrays the world's sensors are read into (`World.sensor_rows`), and the true pose and default
    estimates of the robots whose odometry is stepped in one batch (`DefaultOdometry`, which writes
    them). `count` is the number of complete samples: a sample counts once every robot's part of
    it is written (a Ctrl-C half-way leaves the last row uncounted)."""

    def __init__(self, sensors: dict[str, np.dtype], batched: int, capacity: int):
        self.columns = _Columns({"time": row(), "poses": row((batched, 1 + ESTIMATES, 3)), "covariances": row((batched, ESTIMATES, COVARIANCES)), **sensors}, capacity)
        arrays = self.columns.arrays
        self.time, self.poses, self.covariances = arrays["time"], arrays["poses"], arrays["covariances"]
        self.values, self.believed, self.tallies = arrays["values"], arrays["believed"], arrays["tallies"]
        self.count = 0
        self.frame: SensorFrame | None = None
        """The readings of the current sample."""


class RobotLog:
    """Everything one robot did in a run, one row per sample (the start of every step, and the
    end of the run): ground truth and each estimate as (T, 3) arrays, each estimate's covariance
    where it has one as (T, 6) (`bots.uncertainty.COVARIANCE_FIELDS`), its readings as columns,
    and the current sample's readings. Rows live in file-backed arrays allocated once for the whole run
    (`_Columns`): the run's own (`_Samples`) for a robot with the default estimators, else its own;
    so a long run costs bytes of disk per sample, not a Python object per step, and its resident
    memory stays flat."""

    def __init__(self, name: str, spec: RobotSpec, controller_name: str, params: dict[str, str],
                 estimators: list[str], samples: _Samples, index: int, world: World, slot: int | None = None,
                 uncertain: Sequence[str] | None = None):  # fmt: skip
        """`index`: the robot's index in the world; `slot`: its row in the batched odometry (None:
        Python estimators, logged by `append`); `uncertain`: the estimates that have a covariance
        (None: all)."""
        self.name, self.spec, self.controller_name, self.params = name, spec, controller_name, params
        self.index = index
        self.collisions = 0
        self.fell = False
        self.status: str | None = None
        """How its controller ended, where it says ('success', 'failure'; 'running'), else None."""
        self.goal_time: float | None = None
        self.notes: dict[str, list] = {}
        """What the run did other than asked (projected infeasible twists): kind -> [first message, count]."""
        self._samples, self._world = samples, world
        uncertain = list(estimators if uncertain is None else uncertain)
        if slot is None:
            rows = {"poses": row((1 + len(estimators), 3)), "covariances": row((len(uncertain), COVARIANCES))}
            self._columns: _Columns | None = _Columns(rows, len(samples.time))
            self._poses, self._covariances = self._columns.arrays["poses"], self._columns.arrays["covariances"]
        else:
            self._columns = None
            self._poses = samples.poses[:, slot, : 1 + len(estimators)]
            self._covariances = samples.covariances[:, slot, : len(estimators)]
        """Per sample: the true pose, then each estimate (one row to write a sample, not one per
        pose); and the covariances of those in `uncertain`."""
        self._truth = self._poses[:, 0]
        self._estimates = {label: self._poses[:, 1 + k] for k, label in enumerate(estimators)}
        self._uncertain = {label: self._covariances[:, k] for k, label in enumerate(uncertain)}

    @property
    def latest(self) -> Readings | None:
        """The readings of the current sample (what the controller gets this step)."""
        frame = self._samples.frame
        return None if frame is None else frame[self.index]

    def append(self, truth: np.ndarray, estimates: np.ndarray | Sequence[np.ndarray], covariances: Sequence[np.ndarray] = ()) -> None:
        """Log the current sample of a robot with Python estimators: the true pose (3,), the
        estimates, (k, 3) or k poses, and the (3, 3) covariances of those with one."""
        n = self._samples.count
        self._truth[n] = truth
        if len(estimates):
            self._poses[n, 1:] = estimates
        for k, cov in enumerate(covariances):
            self._covariances[n, k] = cov[_UPPER]
        self._columns.release_written(n + 1)

    def release(self, rows: slice) -> None:
        """Take these rows out of resident memory (they stay readable)."""
        if self._columns is not None:
            self._columns.release(rows.start, rows.stop)

    def __len__(self) -> int:
        return self._samples.count

    def note(self, message: str) -> None:
        """Count a message; messages that differ only in their numbers are one kind (bounded memory)."""
        entry = self.notes.setdefault(re.sub(r"-?\d[\d.e+-]*", "#", message), [message, 0])
        entry[1] += 1

    def time_array(self) -> np.ndarray:
        """(T,) sample times (s), the run's (a view)."""
        return self._samples.time[: self._samples.count]

    def truth_array(self) -> np.ndarray:
        """(T, 3) ground-truth poses (a view, no copy)."""
        return self._truth[: self._samples.count]

    def estimate_arrays(self) -> dict[str, np.ndarray]:
        """Estimator name -> (T, 3) estimated poses (views, no copies)."""
        count = self._samples.count
        return {label: poses[:count] for label, poses in self._estimates.items()}

    def covariance_arrays(self) -> dict[str, np.ndarray]:
        """Estimator name -> (T, 6) covariance entries (COVARIANCE_FIELDS: m², m·rad, rad²) of the
        estimates that have one (views, no copies)."""
        count = self._samples.count
        return {label: values[:count] for label, values in self._uncertain.items()}

    def readings(self, rows: slice) -> dict[str, np.ndarray]:
        """This robot's readings of samples `rows` as columns: Readings' field name -> (n, width)
        array (views into the run's columns; not a general chassis's per-wheel fields)."""
        s = self._samples
        return self._world.readings_columns(self.index, s.values[rows], s.believed[rows], s.tallies[rows])


class Ending(StrEnum):
    """How a run ended (`RunResult.reason`). A str: summary.json, tables and comparisons with the
    plain names ("goal") hold its value."""

    DURATION = "duration"
    """It ran for its whole duration."""
    GOAL = "goal"
    """A robot reached a goal area (with `until_goal`)."""
    DONE = "done"
    """Every robot's controller said it is done (its `status` is no longer RUNNING)."""
    QUIT = "quit"
    """The user closed the window (`ctsim play`)."""
    ERROR = "error"
    """A controller failed (raised, returned a bad command, overran its step time): `error` says how."""
    INTERRUPTED = "interrupted"
    """Ctrl-C (SIGINT)."""
    TERMINATED = "terminated"
    """SIGTERM (a job scheduler, `timeout`)."""

    @property
    def signalled(self) -> bool:
        """Whether a signal ended the run (Ctrl-C or SIGTERM): partial results, a status of its own."""
        return self in (Ending.INTERRUPTED, Ending.TERMINATED)


class RunResult:
    """A finished (or stopped) run. `reason` is an `Ending` or what `run`'s `stop_when` answered
    (a referee's verdict); `error` holds the one-line message of a failure."""

    def __init__(self, world: WorldSpec, seed: int, dt: float, robots: list[RobotLog], samples: _Samples):
        self.world, self.seed, self.dt, self.robots = world, seed, dt, robots
        self.reason: Ending | str = Ending.DURATION
        self.error: str | None = None
        self.notes: list[str] = []
        """What the run's guards put back that a controller had changed (`sim.guards`), once each."""
        self._samples = samples

    @property
    def time(self) -> np.ndarray:
        """(T,) sample times (s), a view."""
        return self._samples.time[: self._samples.count]

    def __len__(self) -> int:
        return self._samples.count

    @property
    def duration(self) -> float:
        """Simulated seconds covered (0 before the first sample)."""
        count = self._samples.count
        return float(self._samples.time[count - 1]) if count else 0.0

    def blocks(self, size: int | None = None) -> Iterator[slice]:
        """Row ranges that cover every sample, `size` (default BLOCK) at a time, to read a long run
        through with bounded memory: once the next is asked for, the previous block's rows of the
        run's columns and of every robot's log leave resident memory again."""
        size = size or BLOCK
        for start in range(0, len(self), size):
            rows = slice(start, min(start + size, len(self)))
            yield rows
            self._samples.columns.release(rows.start, rows.stop)
            for log in self.robots:
                log.release(rows)


class Observer(Protocol):
    """Sees a run go by (recorders, progress bars); every method is optional."""

    def on_start(self, world: World, logs: list[RobotLog]) -> None: ...
    def on_sample(self, world: World, logs: list[RobotLog]) -> None: ...
    def on_end(self, result: RunResult) -> None: ...


class RunError(UserError, RuntimeError):
    """A run that could not start (bad setup); the message is for the user."""


class Terminated(KeyboardInterrupt):
    """Raised by a SIGTERM handler (a job scheduler, `timeout`): the run ends as on Ctrl-C."""


"""Steps (s) a run takes: below 0.1 ms a run is millions of steps per simulated minute for nothing
the motors or sensors resolve; above 1 s a robot crosses a maze cell between two sensor reads."""
MAX_DURATION = 1e7
"""Longest run (simulated s, about 116 days): the sweep spec's limit too."""


MAX_STEP_TIMEOUT = 86_400.0
"""Longest wall-clock time limit on a controller step (s): a day; the operating system's timer
holds no more than about 10^8 s."""


class StepTimeout(BaseException):
    """A controller step ran past its time limit (a BaseException, so that a controller's own
    `except Exception` does not swallow it)."""


class StepClock:
    """A time limit on each controller step, kept by SIGALRM: a timer ticks every quarter of the
    limit and raises StepTimeout inside a controller that the last four ticks found in the same
    step (so a step ends between 1 and 1.25 limits). Only in the main thread of a POSIX process
    (signals go there); elsewhere steps are not timed. `busy` is the number of the controller call
    in progress (0: none)."""

    active: StepClock | None = None
    """The clock of the run going on in this process, if any."""

    def __init__(self, limit: float | None):
        if limit is not None and not (isinstance(limit, (int, float)) and 0 < limit <= MAX_STEP_TIMEOUT):
            raise RunError(f"the step time limit must be more than 0 and at most {MAX_STEP_TIMEOUT:,.0f} s (a day), got {limit!r}")
        self.limit = limit
        self.busy = 0
        self._seen, self._ticks, self._previous = 0, 0, None
        self.armed = bool(limit) and hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()

    def __enter__(self) -> StepClock:
        if self.armed:
            self._previous = signal.signal(signal.SIGALRM, self._tick)
            signal.setitimer(signal.ITIMER_REAL, self.limit / 4, self.limit / 4)
            StepClock.active = self
        return self

    def __exit__(self, *exc: object) -> None:
        if self.armed:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, self._previous)
            StepClock.active = None

    def _tick(self, signum: int, frame: object) -> None:
        if self.busy and self.busy == self._seen:
            self._ticks += 1
            if self._ticks >= 4:
                raise StepTimeout
        else:
            self._seen, self._ticks = self.busy, 0


def in_controller() -> bool:
    """Whether a run in this process is inside a controller step right now (a signal handler
    can then raise at once: no ctsim lock is held there)."""
    return StepClock.active is not None and StepClock.active.busy != 0


class Quit(KeyboardInterrupt):
    """Raised by an observer whose user ended the session (a window closed, Esc pressed): the run
    ends where it is, with reason 'quit'."""


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
    sample (a referee), ends the run when it answers a reason (the result's `reason`)."""
    steps = step_count(duration, dt)
    world = World(world_spec, dt=dt, seed=seed)
    placed = [world.add_robot(setup.spec, setup.start, setup.name) for setup in robots]
    _refuse_overlaps(placed)
    # the default estimators of all robots that use them are stepped together, in one compiled pass
    members = [i for i, setup in enumerate(robots) if setup.estimators is None and batched(setup.spec)]
    odometry = DefaultOdometry([robots[i].spec for i in members], np.array([placed[i].pose for i in members]).reshape(-1, 3), members) if members else None
    slot = {i: k for k, i in enumerate(members)}
    samples = _Samples(world.sensor_rows(), len(members), steps + 1)
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
            if stop_when is not None and (reason := stop_when(world, logs)):
                result.reason = reason
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
    world: World, samples: _Samples, logs: list[RobotLog], estimators: list[tuple[int, RobotLog, list[Estimator]]],
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
