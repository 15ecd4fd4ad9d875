"""Robot descriptions as data: geometry, motors and sensor layout of a differential-drive robot,
or of a robot on any wheeled chassis (`chassis`, see `wheeled_robot`).

Body frame: x forward, y left, origin at the middle of the wheel axle (m, rad). A robot other
than the c't-Bot is a different `RobotSpec` (in Python or in a TOML file, see `load_robot`).
"""

from __future__ import annotations

import math
from dataclasses import MISSING, dataclass, field, fields, is_dataclass, replace
from functools import cached_property
from pathlib import Path
from typing import Any, get_args, get_type_hints

from bots.chassis_spec import ChassisSpec, chassis_from_dict, inscribed_radius
from bots.schema import MIN_LENGTH, MIN_MASS, WORLD_EXTENT, FileError, Locator, Problem, check_fields, declared, file_stem, shown
from bots.schema import read_toml as read_located
from bots.sensor_kinds import sections
from sim.errors import UserError

REACH = 2.0
"""Farthest a mount point (sensor, skid) may sit from a robot's reference point (m)."""
_MOUNT = {"kind": "pair", "unit": "m", "low": -REACH, "high": REACH}
_ANGLE = {"unit": "rad", "low": -2 * math.pi, "high": 2 * math.pi}
_RAW = {"unit": "raw units (0..1023)", "low": 0.0, "high": 1023.0}
_RELATIVE = {"low": -0.5, "high": 0.5}

Point = tuple[float, float]
CONTACT_RULES = ("slide", "stop")
IR_VIEWS = ("cone", "pick")
LIGHT_VIEWS = ("surface", "pick")
"""`RobotSpec.contact`: pymunk's contacts, or c't-Sim's rule (the bridge's firmware bots)."""
START_PHASES = ("zero", "random")
"""Where a counter stands within a count at the start (`EncoderSpec.start_phase`)."""


@dataclass(frozen=True)
class MotorSpec:
    """Signed command (-command_max..command_max) -> wheel angular speed, linear like c't-Sim.

    max_wheel_speed: wheel speed at full command (rad/s; the c't-Bot's 151 rpm).
    time_constant: first-order lag of the wheel speed (s); 0 = none.
    max_acceleration: limit on the change of wheel speed (rad/s^2); inf = none.
    """

    max_wheel_speed: float = declared(default=151 / 60 * 2 * math.pi, unit="rad/s", low=0.0, above=True, high=1000.0)
    command_max: float = declared(default=255.0, unit="command units", low=0.0, above=True, high=1e6)
    time_constant: float = declared(default=0.0, unit="s", low=0.0, high=10.0)
    max_acceleration: float = declared(default=math.inf, unit="rad/s^2", low=0.0, above=True, infinite=True)

    def __post_init__(self) -> None:
        check_fields(self)


@dataclass(frozen=True)
class EncoderSpec:
    """Wheel encoders and their systematic and random errors (all off by default).

    diameter_error: relative error of each wheel's real diameter, (left, right); the robot's own
        code believes the nominal diameter, so this is what UMBmark calibrates.
    track_error: relative error of the real track width against the nominal one.
    slip_std: random slip (sqrt m): after rolling d metres a wheel's arc is off by a normal error
        of std slip_std * sqrt(d), independent of the step (variance grows with the distance).
    tick_noise: probability that a tick counted is one too many or one too few (an edge of the
        light barrier that bounces or is missed): per tick, so per wheel turn, at any step.
    start_phase: where each disc stands within a tick at the start: 'zero' (on an edge, as
        c't-Sim: the count lags the wheel by half a tick on average, a bias) or 'random'
        (uniform, from the run's seed, as a real wheel stops anywhere: the count's error has
        zero mean, variance tick²/6, as the estimators believe).
    """

    ticks_per_rev: int = declared("integer", default=60, unit="ticks", low=1, high=2**53)  # (2**40 in tests: "no quantisation")
    diameter_error: Point = declared("pair", default=(0.0, 0.0), unit="relative", **_RELATIVE)
    track_error: float = declared(default=0.0, unit="relative", **_RELATIVE)
    slip_std: float = declared(default=0.0, unit="sqrt m", low=0.0, high=1.0)
    tick_noise: float = declared(default=0.0, unit="probability per tick", low=0.0, high=1.0)
    start_phase: str = declared("text", default="zero", choices=START_PHASES)

    def __post_init__(self) -> None:
        check_fields(self)


@dataclass(frozen=True)
class MouseSpec:
    """Optical mouse sensor (ADNS-2610 on the c't-Bot) at `mount` in the body frame (m).

    dpi: nominal resolution (counts per inch). scale_error: relative error of the real resolution
    (the real c't-Bot reads 415 instead of 400: 0.0375). noise_std: random count error (sqrt m):
    after the floor passed d metres under the sensor each axis is off by std noise_std * sqrt(d)
    metres, independent of the step; a sensor at rest reads no noise.
    max_speed: fastest ground speed it tracks (m/s); faster motion reads zero.
    start_phase: where the floor stands within a count at the start, as `EncoderSpec.start_phase`.
    """

    mount: Point = declared(default=(-0.015, 0.0), **_MOUNT)
    dpi: float = declared(default=400.0, unit="counts per inch", low=0.0, above=True, high=1e15)  # (1e12 in tests: "no quantisation")
    scale_error: float = declared(default=0.0, unit="relative", **_RELATIVE)
    noise_std: float = declared(default=0.0, unit="sqrt m", low=0.0, high=1.0)
    max_speed: float = declared(default=math.inf, unit="m/s", low=0.0, above=True, infinite=True)
    start_phase: str = declared("text", default="zero", choices=START_PHASES)

    def __post_init__(self) -> None:
        check_fields(self)


@dataclass(frozen=True)
class BeliefSpec:
    """What the robot's own estimators believe about its odometry errors: standard deviations of
    the errors it cannot see, as a data sheet states tolerances. Never read from the simulated
    errors (`EncoderSpec`, `MouseSpec`): a real robot does not know its own, and a filter tuned
    for one robot may run on another. A robot file's `[belief]` section sets them.

    The defaults are the c't-Bot's stated figures (`bots.noise` gives each one's source; its
    realistic preset draws true errors of these sizes): wheel_diameter_std, the relative
    tolerance of each wheel's diameter (0.3 %: 0.17 mm of a 56.7 mm hand-mounted tyre);
    track_std, that of the track (1 %: the tyres' 1 mm contact patch on a 97.2 mm track);
    mouse_scale_std, that of the mouse's resolution (3.75 %: the firmware's bot-local.h states the
    real ADNS-2610 at 415 cpi against its nominal 400; at most 25 %: the mouse estimator's sigma points
    reach 3.75 standard deviations, `bots.odometry.layout.MOUSE_NODES`, and a resolution is never
    negative); slip_std (sqrt m), tick_noise (per tick)
    and mouse_noise_std (sqrt m), the random processes as `EncoderSpec` and `MouseSpec` state them.

    diameter_correction (left, right) and track_correction: what a calibration found (`ctsim
    umbmark` writes them, with the stds its intervals leave): the robot's own code believes each
    wheel's diameter and the track the nominal ones times (1 + correction): its estimators, and
    its controllers' own odometry and their speeds turned into motor commands
    (`RobotSpec.believed_wheel_radii`, `believed_track`). Zero: the nominal description.
    """

    wheel_diameter_std: float = declared(default=0.003, unit="relative", low=0.0, high=0.5)
    track_std: float = declared(default=0.01, unit="relative", low=0.0, high=0.5)
    mouse_scale_std: float = declared(default=0.0375, unit="relative", low=0.0, high=0.25)
    slip_std: float = declared(default=0.0004, unit="sqrt m", low=0.0, high=1.0)
    tick_noise: float = declared(default=0.002, unit="probability per tick", low=0.0, high=1.0)
    mouse_noise_std: float = declared(default=0.00033, unit="sqrt m", low=0.0, high=1.0)
    diameter_correction: Point = declared("pair", default=(0.0, 0.0), unit="relative", **_RELATIVE)
    track_correction: float = declared(default=0.0, unit="relative", **_RELATIVE)

    def __post_init__(self) -> None:
        check_fields(self)


@dataclass(frozen=True)
class IRSensorSpec:
    """An IR distance sensor looking along `direction` (rad, body frame) from `position`.

    curve: name of the characteristic file in c't-Sim's `characteristics/` folder or a path to
    such a file; None uses c't-Sim's GP2D12 table for `side`, shipped with ctsim.
    """

    name: str = declared("text")
    position: Point = declared(**_MOUNT)
    direction: float = declared(default=0.0, **_ANGLE)
    side: str = declared("text", default="left", choices=("left", "right"))
    min_range: float = declared(default=0.1, unit="m", low=0.0, high=10.0)
    max_range: float = declared(default=0.8, unit="m", low=0.0, above=True, high=10.0)
    curve: str | None = declared("text", default=None, optional=True)
    noise_std: float = declared(default=0.0, unit="m", low=0.0, high=1.0)
    cone: float = declared(default=math.radians(3.0), unit="rad", low=0.0, high=math.pi / 4)
    """Half-angle (rad) of the cone the sensor sees the nearest body in (c't-Sim: 3°); 0 casts one ray."""
    view: str = declared("text", default="cone", choices=IR_VIEWS)
    """What the cone sees of a wall: 'cone' its nearest point in the cone, or 'pick' what
    c't-Sim's Java3D cone pick finds (`sim.world.kernels.pick`, measured against the real c't-Sim):
    the wall where the cone's axis meets it, its corners in the whole cone and, near a face's
    diagonal, that diagonal; from inside a wall the face it looks out through. Other robots and
    cans are seen in the whole cone."""

    def __post_init__(self) -> None:
        check_fields(self)
        if self.min_range >= self.max_range:
            raise Problem("min_range", f"must be less than max_range ({self.max_range:g} m), not {self.min_range:g}")


@dataclass(frozen=True)
class FloorSensorSpec:
    """A CNY70 reflex sensor looking at the floor from `position` (line and border sensors),
    `height` m above it: like c't-Sim it averages a "+" of rays up to 40° off vertical, which
    meet the floor within height * tan 40° of the mount point (0: the mount point alone)."""

    name: str = declared("text")
    position: Point = declared(**_MOUNT)
    noise_std: float = declared(default=0.0, **_RAW)
    height: float = declared(default=0.0, unit="m", low=0.0, high=1.0)

    def __post_init__(self) -> None:
        check_fields(self)


@dataclass(frozen=True)
class LightSensorSpec:
    """A light-dependent resistor `height` m above the floor, looking horizontally along
    `direction` with a cone of full `opening` (rad; pi sees the whole half-space ahead, as
    c't-Sim's 90-degree half-angle cone); it reads the distance to the nearest lamp surface."""

    name: str = declared("text")
    position: Point = declared(**_MOUNT)
    direction: float = declared(default=0.0, **_ANGLE)
    opening: float = declared(default=math.pi, unit="rad", low=0.0, above=True, high=2 * math.pi)
    reach: float = declared(default=1.0, unit="m", low=0.0, above=True, high=WORLD_EXTENT)
    height: float = declared(default=0.075, unit="m", low=0.0, high=10.0)
    noise_std: float = declared(default=0.0, **_RAW)
    view: str = declared("text", default="surface", choices=LIGHT_VIEWS)
    """What it measures to: 'surface' the nearest lamp sphere's surface, or 'pick' what c't-Sim's
    Java3D cone-ray pick finds on the lamp sphere's mesh (`sim.world.kernels.light_pick`,
    measured against the real c't-Sim)."""

    def __post_init__(self) -> None:
        check_fields(self)


def _with_sensor_lists(cls: type) -> type:
    """Give a robot a field per robot-file section of the sensor registry (`SensorKind.section`),
    a tuple of that section's `sensor` class (of this module), empty by default, after its
    `belief`: a new list of sensors is its registry row, nothing here."""
    hints: dict[str, Any] = {}
    for name, hint in cls.__annotations__.items():
        hints[name] = hint
        if name == "belief":
            for section, sensor in sections().items():
                hints[section] = f"tuple[{sensor}, ...]"  # (read by `dataclass` and `get_type_hints` in this module)
                setattr(cls, section, ())
    cls.__annotations__ = hints
    return cls


@dataclass(frozen=True)
@_with_sensor_lists
class RobotSpec:
    """A differential-drive robot: geometry (m, kg), motors and sensors, and what its own
    estimators believe about their errors (`belief`).

    With `chassis` set, the robot drives that general chassis instead (built by `wheeled_robot`):
    wheel_diameter and track_width then only describe its first wheel for the shared bookkeeping,
    the motor's time constant and acceleration limit act on every wheel, encoders count every wheel.
    """

    name: str = declared("text")
    wheel_diameter: float = declared(unit="m", low=MIN_LENGTH, high=2.0)
    track_width: float = declared(unit="m", low=MIN_LENGTH, high=2 * REACH)
    body_radius: float = declared(unit="m", low=MIN_LENGTH, high=REACH)
    mass: float = declared(default=0.5, unit="kg", low=MIN_MASS, high=1000.0)
    skid: Point = declared(default=(-0.054, 0.0), **_MOUNT)
    motor: MotorSpec = field(default_factory=MotorSpec)
    encoders: EncoderSpec = field(default_factory=EncoderSpec)
    mouse: MouseSpec | None = field(default_factory=MouseSpec)
    belief: BeliefSpec = field(default_factory=BeliefSpec)
    # (here `_with_sensor_lists` puts one tuple of sensors per section of the sensor registry)
    chassis: ChassisSpec | None = None
    contact: str = declared("text", default="slide", choices=CONTACT_RULES)
    """How the body meets walls and other robots: 'slide' (pymunk's contacts: it stops at the
    surface or slides along it) or 'stop' (c't-Sim's rule: a step that would bring it within its
    radius of anything is not made, the robot keeps its last free position and can still turn)."""

    @cached_property
    def wheel_radius(self) -> float:
        """Nominal wheel radius (m)."""
        return self.wheel_diameter / 2

    @cached_property
    def believed_wheel_radii(self) -> tuple[float, float]:
        """Each wheel's radius (m) as the robot's own code believes it (left, right): the nominal
        one times (1 + its calibration's correction, `BeliefSpec.diameter_correction`)."""
        left, right = self.belief.diameter_correction
        return self.wheel_diameter * (1 + left) / 2, self.wheel_diameter * (1 + right) / 2

    @cached_property
    def believed_track(self) -> float:
        """The track (m) as the robot's own code believes it: nominal times (1 + `BeliefSpec.track_correction`)."""
        return self.track_width * (1 + self.belief.track_correction)

    @cached_property
    def max_wheel_surface_speed(self) -> float:
        """Fastest rim speed the motors allow (m/s). (Cached, as `wheel_radius`: the run loop asks
        several times a step.)"""
        return self.motor.max_wheel_speed * self.wheel_radius

    def __post_init__(self) -> None:
        try:
            check_fields(self)
        except Problem as problem:
            raise Problem(problem.key, f"{problem.message} (robot {shown(self.name)})") from None
        if not file_stem(self.name):
            raise Problem("name", f"{shown(self.name)} leaves nothing to name the robot's files by: give it letters or digits")
        if self.chassis is not None and (self.encoders.diameter_error != (0.0, 0.0) or self.encoders.track_error):
            raise Problem("encoders", "diameter_error and track_error describe a differential drive; "
                                      f"give a general chassis's wheels their real radius instead (robot {self.name!r})")
        if self.chassis is None and self.track_width > 2 * self.body_radius + 1e-9:
            raise Problem("track_width", f"{self.track_width:g} m is wider than the body (2 x body_radius = {2 * self.body_radius:g} m; robot {self.name!r})")

    def with_changes(self, **changes: Any) -> RobotSpec:
        """A copy with some fields replaced; nested specs take dicts: `encoders={"slip_std": 0.01}`."""
        resolved = {}
        for key, value in changes.items():
            current = getattr(self, key)
            resolved[key] = replace(current, **value) if is_dataclass(current) and isinstance(value, dict) else value
        return replace(self, **resolved)


_NESTED = {"motor": MotorSpec, "encoders": EncoderSpec, "mouse": MouseSpec, "belief": BeliefSpec}
_LISTS = {section: get_args(get_type_hints(RobotSpec)[section])[0] for section in sections()}
"""Each robot-file section of sensors (the registry's) -> its sensor class (`RobotSpec`'s field declares it)."""


class _Source:
    """Where a robot's data came from, to name file, line and key in each problem."""

    def __init__(self, where: str, locator: Locator | None = None):
        self.where, self.locator = where, locator

    def fail(self, problem: str, table: str | None = None, index: int | None = None, key: str | None = None) -> FileError:
        line = self.locator.line(table, index, key) if self.locator is not None else None
        if line is None and self.locator is not None and table is not None:
            line = self.locator.line(table, index)
        label = "" if table is None else f"[[{table}]] #{index + 1}: " if index is not None else f"[{table}]: "
        return FileError(self.where, line, f"{label}{key + ': ' if key else ''}{problem}")

    def build(self, cls: type, data: Any, table: str | None = None, index: int | None = None,
              make: Any = None, given: tuple[str, ...] = (), optional: tuple[str, ...] = ()) -> Any:
        """`cls(**data)` (or `make(**data)`, which supplies the fields `given` and may do without
        those `optional`), every unknown, missing or bad key a FileError on its line."""
        if not isinstance(data, dict):
            raise self.fail("must be a table", table, index)
        known = [f.name for f in fields(cls) if f.name not in given]
        for key in data:
            if key not in known:
                raise self.fail(f"unknown key; known: {', '.join(known)}", table, index, key)
        for f in fields(cls):
            if f.default is MISSING and f.default_factory is MISSING and f.name not in (*data, *given, *optional):
                raise self.fail("missing", table, index, f.name)
        try:
            return (make or cls)(**data)
        except Problem as problem:
            head, _, rest = problem.key.partition(".")
            if rest and head in _NESTED:  # a nested section's problem, raised again by the robot
                raise self.fail(problem.message, head, None, rest) from None
            raise self.fail(problem.message, table, index, problem.key or None) from None
        except (TypeError, ValueError) as err:
            raise self.fail(str(err), table, index) from None


def wheeled_robot(name: str, chassis: ChassisSpec, body_radius: float | None = None, **fields: Any) -> RobotSpec:
    """A robot on a general chassis; body_radius defaults to the outline's inscribed radius (m)."""
    if body_radius is None:
        if not chassis.outline:
            raise ValueError(f"robot {name!r}: a chassis without an outline needs body_radius (a circle)")
        body_radius = inscribed_radius(chassis.outline)
    first = chassis.chassis
    return RobotSpec(name=name, wheel_diameter=2 * float(first.radius[0]), track_width=body_radius,
                     body_radius=body_radius, chassis=chassis, **fields)


def _chassis_spec(data: Any, source: _Source) -> ChassisSpec:
    if not isinstance(data, dict):
        raise source.fail("must be a table", "chassis")
    try:
        chassis, rest = chassis_from_dict(data, "[chassis]")
    except (TypeError, ValueError) as err:
        raise source.fail(str(err).removeprefix("[chassis]: "), "chassis") from None
    if "mouse2" in rest:
        rest["mouse2"] = source.build(MouseSpec, rest["mouse2"], "chassis.mouse2")
    if "outline" in rest:
        outline = rest["outline"]
        if not isinstance(outline, list) or not all(isinstance(p, list) for p in outline):
            raise source.fail("must be a list of [x, y] points", "chassis", None, "outline")
        rest["outline"] = tuple(tuple(p) for p in outline)
    return source.build(ChassisSpec, rest, "chassis", make=lambda **kw: ChassisSpec(chassis, **kw), given=("chassis",))


def robot_from_dict(data: dict, where: str = "robot", locator: Locator | None = None) -> RobotSpec:
    """Build a `RobotSpec` from plain data (as read from TOML): each problem is a FileError naming
    the file (`where`), the line (with `locator`) and the key. A `[chassis]` table makes it a robot
    on a general chassis (`wheeled_robot`)."""
    source = _Source(where, locator)
    data = dict(data)
    for key, cls in _NESTED.items():
        if key in data:
            data[key] = source.build(cls, data[key], key)
    for key, cls in _LISTS.items():
        if key in data:
            if not isinstance(data[key], list):
                raise source.fail(f"must be written as [[{key}]] tables", None, None, key)
            data[key] = tuple(source.build(cls, item, key, i) for i, item in enumerate(data[key]))
    if "chassis" not in data:
        return source.build(RobotSpec, data)
    chassis = _chassis_spec(data.pop("chassis"), source)
    for key in ("wheel_diameter", "track_width"):  # (the chassis's first wheel gives these)
        data.pop(key, None)
    return source.build(RobotSpec, data, make=lambda **kw: wheeled_robot(chassis=chassis, **kw),
                        given=("chassis", "wheel_diameter", "track_width"), optional=("body_radius",))


def read_toml(path: Path, error: type[Exception] = UserError) -> dict:
    """A TOML file's data (bounded: `bots.schema.read_toml`), or `error("file:line: problem")`."""
    try:
        return read_located(Path(path))[0]
    except FileError as err:
        raise error(str(err)) from None


def load_robot(path: str | Path) -> RobotSpec:
    """Read a robot description from a TOML file (the keys are the `RobotSpec` fields)."""
    data, locator = read_located(Path(path))
    return robot_from_dict(data, str(path), locator)
