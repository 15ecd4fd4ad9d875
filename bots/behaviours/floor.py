"""Behaviours on the floor sensors: follow a line, keep out of holes."""

from __future__ import annotations

import math

from bots.behaviours.base import (
    BORDER_DANGEROUS,
    LINE_SENSE,
    SPEED_NORMAL,
    Behaviour,
    Sequence,
)
from bots.behaviours.motion import DriveDistance, Turn
from bots.commands import Command, Twist
from bots.controller import Status, make, register
from bots.readings import Readings

LAP_MIN_M = 1.0
"""Travel (m) before a return to the start pose counts as a lap."""
LAP_RADIUS_M = 0.05
"""How close (m) to its start pose a follower must come to count a lap."""


@register("follow_line")
class FollowLine(Behaviour):
    """Follows a black line with the two CNY70 line sensors, straddling it: while both see it the
    robot drives straight, when one loses it the robot curves back towards the other. When both
    lose it (a gap or a sharp bend) it keeps going straight for `gap_m`, then searches by turning
    to either side, further each time, and fails after a full turn without the line.

    `laps` > 0 ends with SUCCESS after that many returns to the start pose (by odometry)."""

    def __init__(
        self,
        speed_m_s: float = SPEED_NORMAL,
        laps: int = 0,
        gap_m: float = 0.1,
        curvature_per_m: float = 12.0,
        threshold: int = LINE_SENSE,
    ):
        if speed_m_s <= 0 or laps < 0 or gap_m < 0:
            raise ValueError("need a positive speed and non-negative laps and gap")
        self.speed = speed_m_s
        self.laps = laps
        self.gap = gap_m
        self.curvature = curvature_per_m
        self.threshold = threshold

    def start(self) -> None:
        self.need("line", 2)
        self.side = 1.0  # where the line was last seen alone: +1 left, -1 right
        self.lost_at: float | None = None  # travel when both sensors lost the line
        self.search: Behaviour | None = None
        self.sweep = 0
        self.travel = 0.0
        self.last_pose = self.pose
        self.laps_done = 0
        self.away = False

    def act(self, t: float, readings: Readings) -> Command:
        self._count_laps()
        if self.laps and self.laps_done >= self.laps:
            return self.finish()
        left, right = (readings.line[:2] > self.threshold).tolist()
        if left or right:
            self.lost_at, self.search, self.sweep = None, None, 0
            if left != right:
                self.side = 1.0 if left else -1.0
                return Twist(self.speed, self.side * self.speed * self.curvature)
            return Twist(self.speed, 0.0)
        if self.lost_at is None:
            self.lost_at = self.travel
        if self.travel - self.lost_at < self.gap:
            return Twist(self.speed, 0.0)
        return self._search(t, readings)

    def _search(self, t: float, readings: Readings) -> Command:
        """Sweep left and right of the heading, 60 degrees further each time, first towards the side
        the line was last seen on."""
        if self.search is None or self.search.status is not Status.RUNNING:
            self.sweep += 1
            if self.sweep > 6:
                return self.finish(Status.FAILURE)
            angle = 60.0 * self.sweep * (1 if self.sweep % 2 else -1) * self.side
            self.search = self.run(Turn(angle, self.speed))
        return self.search.step(t, readings)

    def _count_laps(self) -> None:
        pose = self.pose
        self.travel += math.hypot(pose[0] - self.last_pose[0], pose[1] - self.last_pose[1])
        self.last_pose = pose
        near = math.hypot(pose[0], pose[1]) < LAP_RADIUS_M
        if self.travel > LAP_MIN_M * (self.laps_done + 1) and near and self.away:
            self.laps_done += 1
            self.away = False
        self.away = self.away or not near


@register("avoid_holes")
class AvoidHoles(Behaviour):
    """A reflex around another behaviour (`inner`, a registered name or a behaviour): while a border
    sensor reads above `threshold` (an abyss ahead) it backs off `back_m` and turns `turn_deg` away
    from the side that saw it, then lets the inner behaviour carry on. Ends as the inner one does."""

    def __init__(
        self,
        inner: str | Behaviour = "wander",
        back_m: float = 0.05,
        turn_deg: float = 120.0,
        threshold: int = BORDER_DANGEROUS,
        speed_m_s: float = SPEED_NORMAL,
    ):
        self.inner = make(inner) if isinstance(inner, str) else inner
        self.back = abs(back_m)
        self.turn = abs(turn_deg)
        self.threshold = threshold
        self.speed = speed_m_s

    def start(self) -> None:
        self.need("border", 1)
        self.run(self.inner)
        self.escape: Behaviour | None = None

    def act(self, t: float, readings: Readings) -> Command:
        danger = [value > self.threshold for value in readings.border.tolist()]
        if self.escape is None and any(danger):
            away = -1.0 if danger[0] and not danger[-1] else 1.0  # left sensor: turn right
            self.escape = self.run(Sequence(DriveDistance(-self.back, self.speed), Turn(away * self.turn, self.speed)))
        if self.escape is not None:
            command = self.escape.step(t, readings)
            if self.escape.status is Status.RUNNING:
                return command
            self.escape = None
        command = self.inner.step(t, readings)
        return command if self.inner.status is Status.RUNNING else self.finish(self.inner.status)
