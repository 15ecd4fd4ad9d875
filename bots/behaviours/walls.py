"""Behaviours on the IR distance sensors: solve a maze by following a wall, wander about."""

from __future__ import annotations

import math
from collections.abc import Generator

import numpy as np

from bots.behaviours.base import GROUND_GOAL, SPEED_NORMAL, Behaviour, Look, Plan
from bots.behaviours.motion import DriveDistance, DriveTo, Turn
from bots.commands import Command, Twist
from bots.controller import Status, register
from sim.kinematics import relative_increment, wrap_angle
from sim.world.readings import Readings

GOAL_TOLERANCE = 0x10
"""How far (raw units) a line sensor may read from GROUND_GOAL on the goal floor."""


def clear_ahead(readings: Readings, beyond_m: float) -> bool:
    """Whether both IR sensors see nothing nearer than `beyond_m` (nan: nothing within range).
    A wall closer than the sensors' 0.1 m reads as a false 0.1-0.2 m on the curve's fold-back, so
    anything below about 0.25 m means blocked."""
    distance = readings.ir_distance
    return bool(np.all(np.isnan(distance) | (distance > beyond_m)))


@register("solve_maze")
@register("follow_wall")
class SolveMaze(Plan):
    """Left- or right-hand wall follower for c't-Sim mazes, whose rooms lie on a grid of `cell_m`
    aligned with the start heading. In each room it looks to the preferred side, ahead and to the
    other side (turning to face each way: the c't-Bot's IR sensors only look forward), takes the
    first open way, else turns back, and drives to the next room's centre by its own odometry.
    Succeeds on the goal floor (the line sensors read GROUND_GOAL), after driving onto it."""

    def __init__(self, hand: str = "right", cell_m: float = 0.48, speed_m_s: float = SPEED_NORMAL, max_rooms: int = 400):
        if hand not in ("left", "right"):
            raise ValueError(f"hand must be 'left' or 'right', got {hand!r}")
        if cell_m <= 0 or speed_m_s <= 0:
            raise ValueError("need a positive cell size and speed")
        self.first = 1 if hand == "left" else -1  # quarter turns, counter-clockwise positive
        self.cell = cell_m
        self.speed = speed_m_s
        self.max_rooms = max_rooms

    def start(self) -> None:
        self.need("ir", 1)
        self.need("line", 1)
        self.entering: Behaviour | None = None
        super().start()

    def act(self, t: float, readings: Readings) -> Command:
        if self.entering is None and np.any(np.abs(readings.line - GROUND_GOAL) <= GOAL_TOLERANCE):
            self.entering = self.run(DriveDistance(self.cell / 4, self.speed))
        if self.entering is None:
            return super().act(t, readings)
        command = self.entering.step(t, readings)
        return command if self.entering.status is Status.RUNNING else self.finish(self.entering.status)

    def _face(self, quarter: int) -> Turn:
        return Turn(math.degrees(float(wrap_angle(quarter * math.pi / 2 - self.pose[2]))), self.speed)

    def _look(self, quarter: int) -> Generator[Behaviour, Status, bool]:
        """Face the way `quarter` and tell whether it is open to the next room."""
        yield self._face(quarter)
        look = Look()
        yield look
        return clear_ahead(look.readings, self.cell / 2)

    def plan(self) -> Generator[Behaviour, Status, Status | None]:
        facing, room = 0, np.zeros(2)
        for _ in range(self.max_rooms):
            ahead = yield from self._look(facing)  # no turn needed
            if (yield from self._look(facing + self.first)):
                facing += self.first
            elif not ahead:
                facing += -self.first if (yield from self._look(facing - self.first)) else 2
            yield self._face(facing)
            room += np.rint([math.cos(facing * math.pi / 2), math.sin(facing * math.pi / 2)])
            local = relative_increment(self.pose, np.array([*(room * self.cell), 0.0]))
            if (yield DriveTo(local[0], local[1], self.speed)) is Status.FAILURE:
                return Status.FAILURE
        return Status.FAILURE


@register("wander")
class Wander(Behaviour):
    """Explores: drives ahead and, when an IR sensor sees something within `clearance_m`, turns away
    (towards the side that sees less), by 90 degrees or more until the way is clear."""

    def __init__(self, speed_m_s: float = SPEED_NORMAL, clearance_m: float = 0.25):
        self.speed = speed_m_s
        self.clearance = clearance_m

    def start(self) -> None:
        self.need("ir", 2)
        self.turning: Behaviour | None = None

    def act(self, t: float, readings: Readings) -> Command:
        if self.turning is not None and self.turning.status is Status.RUNNING:
            return self.turning.step(t, readings)
        if clear_ahead(readings, self.clearance):
            return Twist(self.speed, 0.0)
        left, right = np.nan_to_num(readings.ir_distance[:2], nan=math.inf)
        self.turning = self.run(Turn(90.0 if left >= right else -90.0, self.speed))
        return self.turning.step(t, readings)
