"""Robot descriptions as data: geometry, motors and sensor layout of a differential-drive robot,
or of a robot on any wheeled chassis (`chassis`, see `wheeled_robot`).

Body frame: x forward, y left, origin at the middle of the wheel axle (m, rad). A robot other
than the c't-Bot is a different `RobotSpec` (in Python or in a TOML file, see `load_robot`).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import MISSING, dataclass, field, fields, is_dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import Any

from bots.chassis_spec import ChassisSpec, chassis_from_dict, inscribed_radius

Point = tuple[float, float]
CONTACT_RULES = ("slide", "stop")
IR_VIEWS = ("cone", "axis")
"""`RobotSpec.contact`: pymunk's contacts, or c't-Sim's rule (the bridge's firmware bots)."""


@dataclass(frozen=True)
class MotorSpec:
    """Signed command (-command_max..command_max) -> wheel angular speed, linear like c't-Sim.

    max_wheel_speed: wheel speed at full command (rad/s; the c't-Bot's 151 rpm).
    time_constant: first-order lag of the wheel speed (s); 0 = none.
    max_acceleration: limit on the change of wheel speed (rad/s^2); inf = none.
    """

    max_wheel_speed: float = 151 / 60 * 2 * math.pi
    command_max: float = 255.0
    time_constant: float = 0.0
    max_acceleration: float = math.inf


@dataclass(frozen=True)
class EncoderSpec:
    """Wheel encoders and their systematic and random errors (all off by default).

    diameter_error: relative error of each wheel's real diameter, (left, right); the robot's own
        code believes the nominal diameter, so this is what UMBmark calibrates.
    track_error: relative error of the real track width against the nominal one.
    slip_std: relative random slip per step (std of a normal factor on each wheel's arc).
    tick_noise: probability per step of a spurious +-1 tick on a wheel.
    """

    ticks_per_rev: int = 60
    diameter_error: Point = (0.0, 0.0)
    track_error: float = 0.0
    slip_std: float = 0.0
    tick_noise: float = 0.0


@dataclass(frozen=True)
class MouseSpec:
    """Optical mouse sensor (ADNS-2610 on the c't-Bot) at `mount` in the body frame (m).

    dpi: nominal resolution (counts per inch). scale_error: relative error of the real resolution
    (the real c't-Bot reads 415 instead of 400: 0.0375). noise_std: counts per step (std).
    max_speed: fastest ground speed it tracks (m/s); faster motion reads zero.
    """

    mount: Point = (-0.015, 0.0)
    dpi: float = 400.0
    scale_error: float = 0.0
    noise_std: float = 0.0
    max_speed: float = math.inf


@dataclass(frozen=True)
class IRSensorSpec:
    """An IR distance sensor looking along `direction` (rad, body frame) from `position`.

    curve: name of the characteristic file in c't-Sim's `characteristics/` folder or a path to
    such a file; None uses c't-Sim's GP2D12 table for `side`, shipped with ctsim.
    """

    name: str
    position: Point
    direction: float = 0.0
    side: str = "left"
    min_range: float = 0.1
    max_range: float = 0.8
    curve: str | None = None
    noise_std: float = 0.0
    cone: float = math.radians(3.0)
    """Half-angle (rad) of the cone the sensor sees the nearest body in (c't-Sim: 3°); 0 casts one ray."""
    view: str = "cone"
    """What the cone sees of a wall: 'cone' its nearest point in the cone, or 'axis' what
    c't-Sim's Java3D pick finds (measured against the real c't-Sim): the wall where the cone's axis
    meets it, and its corners inside the cone. Other robots and cans are seen in the whole cone."""

    def __post_init__(self) -> None:
        if self.view not in IR_VIEWS:
            raise ValueError(f"IR sensor {self.name!r}: view must be one of {', '.join(IR_VIEWS)}, got {self.view!r}")


@dataclass(frozen=True)
class FloorSensorSpec:
    """A CNY70 reflex sensor looking at the floor from `position` (line and border sensors),
    `height` m above it: like c't-Sim it averages a "+" of rays up to 40° off vertical, which
    meet the floor within height * tan 40° of the mount point (0: the mount point alone)."""

    name: str
    position: Point
    noise_std: float = 0.0
    height: float = 0.0


@dataclass(frozen=True)
class LightSensorSpec:
    """A light-dependent resistor `height` m above the floor, looking horizontally along
    `direction` with a cone of full `opening` (rad; pi sees the whole half-space ahead, as
    c't-Sim's 90-degree half-angle cone); it reads the distance to the nearest lamp surface."""

    name: str
    position: Point
    direction: float = 0.0
    opening: float = math.pi
    reach: float = 1.0
    height: float = 0.075
    noise_std: float = 0.0


@dataclass(frozen=True)
class RobotSpec:
    """A differential-drive robot: geometry (m, kg), motors and sensors.

    With `chassis` set, the robot drives that general chassis instead (built by `wheeled_robot`):
    wheel_diameter and track_width then only describe its first wheel for the shared bookkeeping,
    the motor's time constant and acceleration limit act on every wheel, encoders count every wheel.
    """

    name: str
    wheel_diameter: float
    track_width: float
    body_radius: float
    mass: float = 0.5
    skid: Point = (-0.054, 0.0)
    motor: MotorSpec = field(default_factory=MotorSpec)
    encoders: EncoderSpec = field(default_factory=EncoderSpec)
    mouse: MouseSpec | None = field(default_factory=MouseSpec)
    ir: tuple[IRSensorSpec, ...] = ()
    line: tuple[FloorSensorSpec, ...] = ()
    border: tuple[FloorSensorSpec, ...] = ()
    light: tuple[LightSensorSpec, ...] = ()
    chassis: ChassisSpec | None = None
    contact: str = "slide"
    """How the body meets walls and other robots: 'slide' (pymunk's contacts: it stops at the
    surface or slides along it) or 'stop' (c't-Sim's rule: a step that would bring it within its
    radius of anything is not made, the robot keeps its last free position and can still turn)."""

    @cached_property
    def wheel_radius(self) -> float:
        """Nominal wheel radius (m)."""
        return self.wheel_diameter / 2

    @cached_property
    def max_wheel_surface_speed(self) -> float:
        """Fastest rim speed the motors allow (m/s). (Cached, as `wheel_radius`: the run loop asks
        several times a step.)"""
        return self.motor.max_wheel_speed * self.wheel_radius

    def __post_init__(self) -> None:
        problems = [
            f"{name} must be a positive number of metres, got {value!r}"
            for name, value in (
                ("wheel_diameter", self.wheel_diameter),
                ("track_width", self.track_width),
                ("body_radius", self.body_radius),
            )
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0)
        ]
        if self.contact not in CONTACT_RULES:
            problems.append(f"contact must be one of {', '.join(CONTACT_RULES)}, got {self.contact!r}")
        if self.chassis is not None and (self.encoders.diameter_error != (0.0, 0.0) or self.encoders.track_error):
            problems.append("encoders.diameter_error and track_error describe a differential drive; "
                            "give a general chassis's wheels their real radius instead")
        if not problems and self.chassis is None and self.track_width > 2 * self.body_radius + 1e-9:
            problems.append("track_width is wider than the body (2 x body_radius)")
        if problems:
            raise ValueError(f"robot {self.name!r}: " + "; ".join(problems))

    def with_changes(self, **changes: Any) -> RobotSpec:
        """A copy with some fields replaced; nested specs take dicts: `encoders={"slip_std": 0.01}`."""
        resolved = {}
        for key, value in changes.items():
            current = getattr(self, key)
            resolved[key] = replace(current, **value) if is_dataclass(current) and isinstance(value, dict) else value
        return replace(self, **resolved)


_NESTED = {"motor": MotorSpec, "encoders": EncoderSpec, "mouse": MouseSpec}
_LISTS = {"ir": IRSensorSpec, "line": FloorSensorSpec, "border": FloorSensorSpec, "light": LightSensorSpec}


def _build(cls: type, data: dict, where: str) -> Any:
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(data) - known)
    if unknown:
        raise ValueError(f"{where}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(known))}")
    missing = [f.name for f in fields(cls) if f.default is MISSING and f.default_factory is MISSING and f.name not in data]
    if missing:
        raise ValueError(f"{where}: missing key(s) {', '.join(missing)}")
    values = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
    try:
        return cls(**values)
    except TypeError as err:
        raise ValueError(f"{where}: {err}") from None


def wheeled_robot(name: str, chassis: ChassisSpec, body_radius: float | None = None, **fields: Any) -> RobotSpec:
    """A robot on a general chassis; body_radius defaults to the outline's inscribed radius (m)."""
    if body_radius is None:
        if not chassis.outline:
            raise ValueError(f"robot {name!r}: a chassis without an outline needs body_radius (a circle)")
        body_radius = inscribed_radius(chassis.outline)
    first = chassis.chassis
    return RobotSpec(name=name, wheel_diameter=2 * float(first.radius[0]), track_width=body_radius,
                     body_radius=body_radius, chassis=chassis, **fields)


def _chassis_spec(data: dict, where: str) -> ChassisSpec:
    chassis, rest = chassis_from_dict(data, where)
    if isinstance(rest.get("mouse2"), dict):
        rest["mouse2"] = _build(MouseSpec, rest["mouse2"], f"{where}: [chassis.mouse2]")
    if "outline" in rest:
        rest["outline"] = tuple(tuple(p) for p in rest["outline"])
    return _build(ChassisSpec, {"chassis": chassis, **rest}, where)


def robot_from_dict(data: dict, where: str = "robot") -> RobotSpec:
    """Build a `RobotSpec` from plain data (as read from TOML), with messages naming the key.
    A `[chassis]` table makes it a robot on a general chassis (`wheeled_robot`)."""
    data = dict(data)
    for key, cls in _NESTED.items():
        if isinstance(data.get(key), dict):
            data[key] = _build(cls, data[key], f"{where}: [{key}]")
    for key, cls in _LISTS.items():
        if key in data:
            data[key] = tuple(_build(cls, item, f"{where}: [[{key}]] #{i + 1}") for i, item in enumerate(data[key]))
    if not isinstance(data.get("chassis"), dict):
        return _build(RobotSpec, data, where)
    chassis = _chassis_spec(data.pop("chassis"), f"{where}: [chassis]")
    unknown = sorted(set(data) - {f.name for f in fields(RobotSpec)} - {"wheel_diameter", "track_width"})
    if unknown or "name" not in data:
        raise ValueError(f"{where}: " + (f"unknown key(s) {', '.join(unknown)}" if unknown else "missing key name"))
    try:
        return wheeled_robot(chassis=chassis, **{k: tuple(v) if isinstance(v, list) else v for k, v in data.items()
                                                 if k not in ("wheel_diameter", "track_width")})
    except TypeError as err:
        raise ValueError(f"{where}: {err}") from None


def read_toml(path: Path, error: type[Exception] = ValueError) -> dict:
    """A TOML file's data, or `error("path: problem")` for a file that cannot be read or parsed."""
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as err:
        raise error(f"{path}: {err.strerror or err}") from None
    except tomllib.TOMLDecodeError as err:
        raise error(f"{path}: {err}") from None


def load_robot(path: str | Path) -> RobotSpec:
    """Read a robot description from a TOML file (the keys are the `RobotSpec` fields)."""
    return robot_from_dict(read_toml(Path(path)), str(path))
