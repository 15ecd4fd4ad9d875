"""Driving behaviours: stop, drive a distance, turn, go to a pose, drive a square, teleop."""

from __future__ import annotations

import math
from collections.abc import Generator, Iterable

import numpy as np

from bots.behaviours.base import SPEED_NORMAL, Behaviour, Plan, ramp
from bots.commands import STOP, Command, Twist
from bots.controller import Status, register
from bots.readings import Readings
from sim.kinematics import relative_pose, wrap_angle

DISTANCE_TOLERANCE = 2e-4
"""A drive has arrived when it believes itself this close (m)."""
ANGLE_TOLERANCE = math.radians(0.05)
"""A turn has arrived when it believes itself this close (rad)."""
MAX_ARC_HALF_ANGLE = math.radians(45)
"""go_to_pose turns first so that its arc bends by at most twice this (arc <= 1.11 x chord)."""
HEADING_GAIN = 5.0
"""Yaw rate (rad/s) per radian of heading error when holding a line."""
LATERAL_GAIN = 20.0
"""Heading correction (rad) per metre off the line, at most MAX_CORRECTION."""
MAX_CORRECTION = 0.3


@register("idle")
class Idle(Behaviour):
    """Stands still for ever."""

    def act(self, t: float, readings: Readings) -> Command:
        return STOP


@register("stop")
class Stop(Behaviour):
    """Stops and succeeds at once."""

    def act(self, t: float, readings: Readings) -> Command:
        return self.finish()


@register("drive_distance")
class DriveDistance(Behaviour):
    """Drives straight ahead (backwards for a negative distance) and stops after `distance_m` by
    its own odometry, braking on a ramp; holds the line it started on."""

    def __init__(self, distance_m: float = 0.5, speed_m_s: float = SPEED_NORMAL):
        if not (math.isfinite(distance_m) and speed_m_s > 0):
            raise ValueError(f"need a finite distance and a positive speed, got {distance_m} m at {speed_m_s} m/s")
        self.distance = distance_m
        self.speed = speed_m_s

    def act(self, t: float, readings: Readings) -> Command:
        x, y, heading = self.pose
        direction = 1.0 if self.distance >= 0 else -1.0
        remaining = (self.distance - x) * direction
        if remaining <= DISTANCE_TOLERANCE:
            return self.finish()
        wanted = -direction * min(max(LATERAL_GAIN * y, -MAX_CORRECTION), MAX_CORRECTION)
        return Twist(direction * ramp(remaining, self.speed, self.dt), HEADING_GAIN * wrap_angle(wanted - heading))


@register("turn")
class Turn(Behaviour):
    """Turns on the spot by `angle_deg` (counter-clockwise positive, several turns allowed), the
    wheels at `speed_m_s`, braking on a ramp like the firmware's bot_turn."""

    def __init__(self, angle_deg: float = 90.0, speed_m_s: float = SPEED_NORMAL):
        if not (math.isfinite(angle_deg) and speed_m_s > 0):
            raise ValueError(f"need a finite angle and a positive speed, got {angle_deg} deg at {speed_m_s} m/s")
        self.angle = math.radians(angle_deg)
        self.speed = speed_m_s

    def act(self, t: float, readings: Readings) -> Command:
        error = self.angle - self.heading
        if abs(error) <= ANGLE_TOLERANCE:
            return self.finish()
        half_track = self.robot.believed_track / 2
        rim = ramp(abs(error) * half_track, self.speed, self.odometry.dt)
        return Twist(0.0, math.copysign(rim / half_track, error))


class DriveTo(Behaviour):
    """Drives to the point (x_m, y_m) of its own frame on the circular arc that starts along the
    current heading, re-planned every step, braking on the arc length left."""

    def __init__(self, x_m: float, y_m: float, speed_m_s: float = SPEED_NORMAL):
        self.target = (float(x_m), float(y_m), 0.0)
        self.speed = speed_m_s

    def act(self, t: float, readings: Readings) -> Command:
        local = relative_pose(self.pose, self.target)
        distance = math.hypot(local[0], local[1])
        if distance <= DISTANCE_TOLERANCE:
            return self.finish()
        bend = math.atan2(local[1], local[0])  # half the heading change on the arc to the target
        if abs(bend) > math.pi / 2:
            return self.finish(Status.FAILURE)  # passed it: the arc would be most of a circle
        sin_bend = math.sin(bend)
        length = distance if bend == 0 else distance * bend / sin_bend
        curvature = 2 * sin_bend / distance
        v = ramp(length, self.speed, self.odometry.dt)
        return Twist(v, v * curvature)


@register("go_to_pose")
class GoToPose(Plan):
    """Goes to (x_m, y_m) and turns to heading_deg, all in its own start frame, like the firmware's
    bot_goto_pos: turn so that one circular arc ends at the target close to the final heading,
    drive the arc, then turn to the final heading."""

    def __init__(self, x_m: float = 0.5, y_m: float = 0.0, heading_deg: float = 0.0, speed_m_s: float = SPEED_NORMAL):
        if not all(math.isfinite(v) for v in (x_m, y_m, heading_deg)) or speed_m_s <= 0:
            raise ValueError("need a finite target and a positive speed")
        self.target = (x_m, y_m, math.radians(heading_deg))
        self.speed = speed_m_s

    def plan(self) -> Generator[Behaviour, Status, Status | None]:
        x, y, heading = self.pose
        gx, gy, final = self.target
        if math.hypot(gx - x, gy - y) > DISTANCE_TOLERANCE:
            bearing = math.atan2(gy - y, gx - x)
            departure = bearing + float(np.clip(wrap_angle(bearing - final), -MAX_ARC_HALF_ANGLE, MAX_ARC_HALF_ANGLE))
            yield Turn(math.degrees(float(wrap_angle(departure - heading))), self.speed)
            local = relative_pose(self.pose, (gx, gy, 0.0))
            if (yield DriveTo(local[0], local[1], self.speed)) is Status.FAILURE:
                return Status.FAILURE
        yield Turn(math.degrees(float(wrap_angle(final - self.pose[2]))), self.speed)
        return None


def polygon_legs(corners: Iterable[tuple[float, float]], speed: float, owner: Behaviour) -> Generator[Behaviour, Status, None]:
    """Turn towards each corner and drive straight to it, planned from `owner`'s pose on arrival."""
    for cx, cy in corners:
        x, y, heading = owner.pose
        yield Turn(math.degrees(float(wrap_angle(math.atan2(cy - y, cx - x) - heading))), speed)
        x, y, _ = owner.pose
        yield DriveDistance(math.hypot(cx - x, cy - y), speed)


@register("square")
class Square(Plan):
    """UMBmark's test path: `laps` squares of side `side_m` (counter-clockwise unless `clockwise`),
    turning on the spot at the corners, back to the start pose."""

    def __init__(self, side_m: float = 0.5, clockwise: bool = False, laps: int = 1, speed_m_s: float = SPEED_NORMAL):
        if not (side_m > 0 and laps >= 1 and speed_m_s > 0):
            raise ValueError(f"need a positive side, laps and speed, got {side_m} m, {laps}, {speed_m_s} m/s")
        self.side = side_m
        self.sign = -1.0 if clockwise else 1.0
        self.laps = laps
        self.speed = speed_m_s

    def plan(self) -> Generator[Behaviour, Status, Status | None]:
        s, left = self.side, self.sign * self.side
        yield from polygon_legs([(s, 0.0), (s, left), (0.0, left), (0.0, 0.0)] * self.laps, self.speed, self)
        yield Turn(math.degrees(float(wrap_angle(-self.pose[2]))), self.speed)
        return None


TELEOP_KEYS = {
    "up": (1, 0), "w": (1, 0),
    "down": (-1, 0), "s": (-1, 0),
    "left": (0, 1), "a": (0, 1),
    "right": (0, -1), "d": (0, -1),
}  # fmt: skip
"""Key name -> (forward, counter-clockwise) direction it asks for."""


@register("teleop")
class Teleop(Behaviour):
    """Keyboard driving: the window reports keys with `press`/`release` (or `set_keys`); arrows or
    w/a/s/d give forward speed and yaw rate, opposite keys cancel. Never ends."""

    def __init__(self, speed_m_s: float = SPEED_NORMAL, turn_deg_s: float = 90.0):
        self.speed = speed_m_s
        self.turn_rate = math.radians(turn_deg_s)
        self.keys: set[str] = set()

    def press(self, key: str) -> None:
        """A key went down (names as in TELEOP_KEYS; others are ignored)."""
        self.keys.add(key.lower())

    def release(self, key: str) -> None:
        """A key went up."""
        self.keys.discard(key.lower())

    def set_keys(self, keys: Iterable[str]) -> None:
        """All the keys held now."""
        self.keys = {key.lower() for key in keys}

    def step(self, t: float, readings: Readings) -> Command:
        """The keys' command: driving by hand needs no odometry, so any chassis can be driven."""
        return self.act(t, readings)

    def act(self, t: float, readings: Readings) -> Command:
        forward = sum(TELEOP_KEYS[k][0] for k in self.keys if k in TELEOP_KEYS)
        turn = sum(TELEOP_KEYS[k][1] for k in self.keys if k in TELEOP_KEYS)
        return Twist(self.speed * forward, self.turn_rate * turn)
