"""A general wheeled chassis on a robot: the core's `Chassis`, the body outline and the drive limits.

A robot description (`bots.spec.RobotSpec`) with a `chassis` drives any wheeled chassis instead of
the c't-Bot's two wheels. The chassis comes from a preset of the kinematics core (by name, with the
preset's keyword parameters) or from a list of wheels (type, placement, radius, steering and rim-speed
limits), as data in Python or in a robot TOML file's `[chassis]` table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from sim.kinematics import chassis_presets
from sim.kinematics.chassis import Chassis, Wheel, WheelType

Point = tuple[float, float]

PRESETS = {
    "differential": chassis_presets.differential_drive,
    "tricycle": chassis_presets.tricycle,
    "ackermann": chassis_presets.ackermann,
    "mecanum4": chassis_presets.mecanum4,
    "omni3": chassis_presets.omni3,
    "omni4": chassis_presets.omni4,
    "steered3": chassis_presets.steered3,
    "steered4": chassis_presets.steered4,
}
"""The core's chassis presets by name (their keyword parameters in m, rad, m/s)."""

_WHEEL_TYPES = {t.name.lower(): t for t in WheelType}
_WHEEL_KEYS = {"type", "x", "y", "heading", "radius", "gamma", "offset", "driven", "max_speed", "steer_limits", "name"}


@dataclass(frozen=True)
class ChassisSpec:
    """The drive of a robot with a general chassis.

    chassis: the core's chassis (wheels, nominal state); outline: the body's convex polygon (m, body
    frame, counter-clockwise, around the reference point), () for a circle of the robot's body_radius;
    steer_rate: fastest steering of a steered wheel (rad/s); mouse2: an optional second mouse sensor
    (a `MouseSpec`); infeasible: what a twist or OCP command the chassis cannot perform (outside its
    feasible set, or beyond its steering limits) does, "refuse" (the default: the run stops with a
    message naming the wheels) or "project" (the nearest feasible twist, then the tightest turn the
    steering allows, is driven and the run's notes say so; see `bots.chassis_commands`).
    """

    chassis: Chassis
    outline: tuple[Point, ...] = ()
    steer_rate: float = math.inf
    mouse2: Any = None
    infeasible: Literal["refuse", "project"] = "refuse"

    def __post_init__(self) -> None:
        problems = []
        if not self.steer_rate > 0:
            problems.append(f"steer_rate must be > 0 rad/s, got {self.steer_rate!r}")
        if self.infeasible not in ("refuse", "project"):
            problems.append(f"infeasible must be 'refuse' or 'project', got {self.infeasible!r}")
        if self.outline:
            problems += outline_problems(self.outline)
        if problems:
            raise ValueError("chassis: " + "; ".join(problems))

    @property
    def wheel_count(self) -> int:
        """Number of wheels."""
        return self.chassis.n


def outline_problems(outline: tuple[Point, ...]) -> list[str]:
    """What is wrong with a body outline: at least 3 vertices, convex, counter-clockwise, around (0, 0)."""
    v = np.asarray(outline, dtype=float)
    if v.ndim != 2 or v.shape[1] != 2 or len(v) < 3 or not np.all(np.isfinite(v)):
        return ["outline must be at least 3 finite (x, y) vertices in metres"]
    edges = np.roll(v, -1, axis=0) - v
    turns = edges[:, 0] * np.roll(edges, -1, axis=0)[:, 1] - edges[:, 1] * np.roll(edges, -1, axis=0)[:, 0]
    if np.any(turns <= 0):
        return ["outline must be a convex polygon with counter-clockwise vertices"]
    if inscribed_radius(outline) <= 0:
        return ["outline must contain the reference point (0, 0) in its interior"]
    return []


def inscribed_radius(outline: tuple[Point, ...]) -> float:
    """Radius (m) of the largest circle around the reference point inside a convex CCW outline
    (negative if the point is outside): the distance to the nearest edge line."""
    v = np.asarray(outline, dtype=float)
    edges = np.roll(v, -1, axis=0) - v
    cross = edges[:, 0] * (0 - v[:, 1]) - edges[:, 1] * (0 - v[:, 0])
    return float(np.min(cross / np.hypot(edges[:, 0], edges[:, 1])))


def wheel_from_dict(data: dict, where: str) -> Wheel:
    """One wheel from a TOML table: type, x, y (m), heading (rad, rolling direction), radius (m), and
    optionally gamma (rad, omni rollers), offset (m, castor), driven, max_speed (m/s), steer_limits, name."""
    unknown = sorted(set(data) - _WHEEL_KEYS)
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(_WHEEL_KEYS))}")
    missing = sorted({"type", "x", "y", "radius"} - set(data))
    if missing:
        raise ValueError(f"{where}: missing key(s) {', '.join(missing)}")
    kind = _WHEEL_TYPES.get(str(data["type"]).lower())
    if kind is None:
        raise ValueError(f"{where}: type {data['type']!r} is not one of {', '.join(_WHEEL_TYPES)}")
    extra = {k: v for k, v in data.items() if k not in ("type", "x", "y", "heading")}
    if "steer_limits" in extra:
        extra["steer_limits"] = tuple(float(a) for a in extra["steer_limits"])
    try:
        return Wheel.placed(kind, float(data["x"]), float(data["y"]), float(data.get("heading", 0.0)), **extra)
    except (TypeError, ValueError) as err:
        raise ValueError(f"{where}: {err}") from None


def chassis_from_dict(data: dict, where: str = "chassis") -> tuple[Chassis, dict]:
    """The core chassis a `[chassis]` table names (`preset` plus its parameters, or `[[chassis.wheels]]`),
    and the table's remaining keys (outline, steer_rate, infeasible, mouse2)."""
    data = dict(data)
    preset, wheels = data.pop("preset", None), data.pop("wheels", None)
    if (preset is None) == (wheels is None):
        raise ValueError(f"{where}: give either preset = NAME (one of {', '.join(PRESETS)}) or [[chassis.wheels]]")
    if wheels is not None:
        built = [wheel_from_dict(w, f"{where}: [[wheels]] #{i + 1}") for i, w in enumerate(wheels)]
        try:
            return Chassis.from_wheels(built), data
        except ValueError as err:
            raise ValueError(f"{where}: {err}") from None
    if preset not in PRESETS:
        raise ValueError(f"{where}: unknown preset {preset!r} (known: {', '.join(PRESETS)})")
    factory = PRESETS[preset]
    own = {"outline", "steer_rate", "infeasible", "mouse2"}
    params = {k: v for k, v in data.items() if k not in own}
    try:
        chassis = factory(**params)
    except TypeError as err:
        raise ValueError(f"{where}: preset {preset!r}: {err}") from None
    return chassis, {k: v for k, v in data.items() if k in own}
