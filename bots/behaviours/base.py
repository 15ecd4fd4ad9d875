"""What every behaviour shares: its own odometry, its own frame, and running other behaviours.

A behaviour knows where it is only from its readings: the root of a behaviour tree keeps a
`TickOdometry` fed with every step's encoder ticks; the behaviours it runs share that estimator and
see poses in their own frame, the pose at the moment they were started being (0, 0, 0). Poses are
tuples of plain floats: a behaviour does a few sums on one pose a step, where numpy's per-call cost
would be most of the work.
"""

from __future__ import annotations

import math
from collections.abc import Generator

import numpy as np

from bots.commands import STOP, Command, wheel_speeds_for
from bots.controller import Status
from bots.readings import Readings
from bots.spec import RobotSpec
from sim.kinematics import Pose, advance_floats, arcs_from_ticks, relative_pose
from sim.kinematics.step import DEFAULT_DT

# The firmware's speeds (BOT_SPEED_* in mm/s) as rim speeds in m/s.
SPEED_SLOW = 0.05
SPEED_FOLLOW = 0.07
SPEED_MEDIUM = 0.10
SPEED_NORMAL = 0.15
SPEED_FAST = 0.25

LINE_SENSE = 0x350
"""Line sensor value above which the firmware (in the simulator) sees the black line."""
BORDER_DANGEROUS = 0x3A0
"""Border sensor value above which the firmware sees an abyss."""
GROUND_GOAL = 0x221
"""What the CNY70 sensors read on c't-Sim's green goal floor."""

DECELERATION = 0.5
"""Braking ramp for rim speeds (m/s^2): 0.15 m/s comes to rest over 22 mm."""
MIN_SPEED = 0.01
"""Slowest rim speed of a ramp (m/s) until the last step, which lands on the target exactly."""
RUNNING = Status.RUNNING
"""(A module name: an enum member read off its class costs 0.1 µs, and a step asks a few times.)"""


def ramp(remaining: float, top: float, dt: float) -> float:
    """Speed (>= 0) for `remaining` metres to go: `top`, braking at DECELERATION, and no more than
    lands exactly on the target within this step."""
    if remaining <= 0:
        return 0.0
    # max(min(top, stopping), MIN_SPEED), then min(that, per_step), as comparisons: a call of a
    # builtin costs more than the sums here (each picks its first argument on a tie, as these do)
    stopping = math.sqrt(2 * DECELERATION * remaining)
    braking = stopping if stopping < top else top
    braking = MIN_SPEED if MIN_SPEED > braking else braking
    per_step = remaining / dt
    return per_step if per_step < braking else braking


class TickOdometry:
    """Encoder odometry that places each wheel within its current tick by the commanded speed.

    A count of N ticks means the wheel has turned between N and N + 1 ticks (the encoders floor the
    running total), so plain counting stops a turn up to a tick late: 1.75 degrees on the c't-Bot.
    Integrating the wheel speeds the robot was commanded, clamped into that interval, removes the
    error while the motors follow and never adds more than a tick when they do not (blocked wheels,
    motor lag, a parent overriding the command)."""

    def __init__(self, robot: RobotSpec):
        self.robot = robot
        self.wheel_tick = tuple(float(arcs_from_ticks(1, radius, robot.encoders.ticks_per_rev)) for radius in robot.believed_wheel_radii)
        """Metres of rim per tick of each wheel (left, right), as the robot believes them."""
        self.metres_per_tick = 0.5 * (self.wheel_tick[0] + self.wheel_tick[1])
        """Their mean (m)."""
        self.track = robot.believed_track
        self._counted = [0.0, 0.0]
        self._turned = [0.0, 0.0]
        self.pose: Pose = (0.0, 0.0, 0.0)
        self.time: float | None = None
        self.dt = DEFAULT_DT

    @property
    def counted(self) -> np.ndarray:
        """Ticks counted per wheel (left, right)."""
        return np.array(self._counted)

    @property
    def turned(self) -> np.ndarray:
        """Ticks each wheel is believed to have turned, within [counted, counted + 1)."""
        return np.array(self._turned)

    def update(self, readings: Readings, speeds: tuple[float, float]) -> None:
        """Take one step's readings; `speeds` are the rim speeds (m/s) commanded in the step before.
        (Plain floats per wheel: numpy's per-call cost on two numbers was most of this step.)"""
        stepped = self.time is not None and readings.time > self.time
        if stepped:
            self.dt = readings.time - self.time
        self.time = readings.time
        left_ticks, right_ticks = readings.encoder_ticks.tolist()
        left = self._wheel_arc(0, left_ticks, speeds[0], stepped) if left_ticks or speeds[0] else 0.0  # (0: standing)
        right = self._wheel_arc(1, right_ticks, speeds[1], stepped) if right_ticks or speeds[1] else 0.0
        if left or right:
            self.pose = advance_floats(self.pose, 0.5 * (left + right), (right - left) / self.track)

    def _wheel_arc(self, wheel: int, ticks: int, speed: float, stepped: bool) -> float:
        """Arc (m) wheel `wheel` is believed to have rolled this step, for a wheel not standing (ticks
        or a speed): its turn by the commanded `speed`, clamped into the tick interval its count now
        allows."""
        before, per_tick = self._turned[wheel], self.wheel_tick[wheel]
        guess = before + float(speed) * self.dt / per_tick if stepped else before
        counted = self._counted[wheel] = self._counted[wheel] + ticks
        low, high = (counted if counted > guess else guess), counted + 1.0  # min(max(guess, counted), high), as comparisons
        turned = self._turned[wheel] = high if high < low else low
        return (turned - before) * per_tick

    def move_by(self, distance: float) -> None:
        """Correct the believed position by `distance` (m) along the heading: for a behaviour that
        knows from another sensor that the wheels slipped."""
        x, y, heading = self.pose
        self.pose = (x + distance * math.cos(heading), y + distance * math.sin(heading), heading)

    def turn_by(self, angle: float) -> None:
        """Correct the believed heading by `angle` (rad), the position kept: for a behaviour that
        knows from another sensor that a tick was spurious."""
        x, y, heading = self.pose
        self.pose = (x, y, heading + angle)


class Behaviour:
    """A controller that may end: `reset`, then `step` until `status` is no longer RUNNING.

    Subclasses implement `act` (and optionally `start`, called on every reset); `pose` is where the
    behaviour believes the robot is in its own frame. A behaviour runs another with `run(child)`,
    which shares its odometry, and then calls the child's `step` itself."""

    status = Status.RUNNING

    def reset(self, robot: RobotSpec, odometry: TickOdometry | None = None) -> None:
        """Start afresh on `robot`; without `odometry` the behaviour keeps its own estimator."""
        self.robot = robot
        self._owns_odometry = odometry is None
        self.odometry = TickOdometry(robot) if odometry is None else odometry
        self.origin = self.odometry.pose
        self.status = Status.RUNNING
        self._command: Command = STOP
        self.start()

    def start(self) -> None:
        """Hook for subclasses: set up the state of one run."""

    def need(self, sensors: str, count: int) -> None:
        """Refuse a robot with fewer than `count` sensors of a kind ('line', 'border', 'ir')."""
        have = len(getattr(self.robot, sensors))
        if have < count:
            raise ValueError(f"{type(self).__name__} needs {count} {sensors} sensors; robot {self.robot.name!r} has {have}")

    def act(self, t: float, readings: Readings) -> Command:
        """This step's command while RUNNING; call `finish` to end."""
        raise NotImplementedError

    def step(self, t: float, readings: Readings) -> Command:
        """Update the odometry (if this behaviour owns it) and act; STOP once finished."""
        if self._owns_odometry:
            self.odometry.update(readings, wheel_speeds_for(self._command, self.robot))
        self._command = self.act(t, readings) if self.status is RUNNING else STOP
        return self._command

    @property
    def pose(self) -> Pose:
        """Believed pose (x m, y m, heading rad) in this behaviour's frame."""
        return relative_pose(self.origin, self.odometry.pose)

    @property
    def heading(self) -> float:
        """Believed heading (rad) in this behaviour's frame: `pose[2]` without its position."""
        return self.odometry.pose[2] - self.origin[2]

    @property
    def dt(self) -> float:
        """The step (s) as the readings show it."""
        return self.odometry.dt

    def finish(self, status: Status = Status.SUCCESS) -> Command:
        """End with `status`; returns STOP for `act` to return."""
        self.status = status
        return STOP

    def run(self, child: Behaviour) -> Behaviour:
        """Start `child` here and now, sharing this behaviour's odometry."""
        child.reset(self.robot, self.odometry)
        return child


class Plan(Behaviour):
    """Behaviours run one after another: `plan()` is a generator that yields each child, gets back
    the status the child ended with, and returns the plan's status (None means SUCCESS). The next
    child is planned when the previous one ends, from the pose reached by then."""

    def plan(self) -> Generator[Behaviour, Status, Status | None]:
        raise NotImplementedError

    def start(self) -> None:
        self._plan = self.plan()
        self._advance(None)

    def _advance(self, status: Status | None) -> None:
        try:
            self._child: Behaviour | None = self.run(self._plan.send(status))
        except StopIteration as end:
            self._child = None
            self.status = end.value or Status.SUCCESS

    def act(self, t: float, readings: Readings) -> Command:
        while (child := self._child) is not None:
            command = child.step(t, readings)
            if child.status is RUNNING:
                return command
            self._advance(child.status)
        return STOP


class Sequence(Plan):
    """Fixed children one after another; fails as soon as one fails."""

    def __init__(self, *children: Behaviour):
        self.children = children

    def plan(self) -> Generator[Behaviour, Status, Status | None]:
        for child in self.children:
            if (yield child) is Status.FAILURE:
                return Status.FAILURE
        return None


class Look(Behaviour):
    """Stands still for `steps` steps and succeeds: a plan's way to sense. Keeps the last step's
    readings and the IR distances averaged over the steps (noise shrinks by the root of the steps;
    nan for a sensor that saw nothing in any of them). With `max_steps` it keeps looking while the
    readings scatter so much that a mean's standard error exceeds `error_m`: readings that do not
    change (no noise) end it after `steps` as before, noisy ones are averaged for longer. With
    `band` (m) only sensors whose mean lies inside it keep it looking: the distances a plan
    measures by, where the others only need to be told apart (near or far)."""

    readings: Readings
    ir_distance: np.ndarray

    def __init__(self, steps: int = 1, max_steps: int | None = None, error_m: float = 0.0, band: tuple[float, float] = (0.0, math.inf)):
        if steps < 1:
            raise ValueError(f"need at least one step, got {steps}")
        self.steps = steps
        self.max_steps = steps if max_steps is None else max(steps, max_steps)
        self.error = error_m
        self.band = band

    def start(self) -> None:
        count = len(self.robot.ir)
        self._sum, self._squares, self._seen = [0.0] * count, [0.0] * count, [0] * count  # per sensor (floats: a step's few sums)
        self._count = 0
        self.raws: list[list[int]] = [[] for _ in range(count)]  # per sensor: every raw value seen

    def act(self, t: float, readings: Readings) -> Command:
        self.readings = readings
        for raws, value in zip(self.raws, readings.ir_raw.tolist()):
            raws.append(value)
        for k, value in enumerate(readings.ir_distance.tolist()):
            if value == value:  # (nan: nothing in view)
                self._sum[k] += value
                self._squares[k] += value * value
                self._seen[k] += 1
        self._count += 1
        if self._count < self.steps or (self._count < self.max_steps and self._scatter() > self.error):
            return STOP
        self.ir_distance = np.array([total / n if n else math.nan for total, n in zip(self._sum, self._seen)])
        return self.finish()

    @property
    def ir_error(self) -> np.ndarray:
        """Each IR sensor's standard error (m) of its mean so far (0 for one sample or none, or
        for readings that did not change)."""
        return np.array([error for _, error in self._means()])

    def _means(self) -> list[tuple[float, float]]:
        """Each sensor's (mean, its standard error) so far (m; 0, 0 for none)."""
        out = []
        for total, squares, seen in zip(self._sum, self._squares, self._seen):
            n = max(seen, 1)
            mean = total / n
            out.append((mean, math.sqrt(max(squares / n - mean * mean, 0.0) / max(n - 1, 1))))
        return out

    def _scatter(self) -> float:
        """The largest standard error (m) of a sensor's mean so far, of those whose mean is in the band."""
        low, high = self.band
        return max((error for (mean, error), seen in zip(self._means(), self._seen) if seen and low < mean < high), default=0.0)
