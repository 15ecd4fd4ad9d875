"""The sensor registry: one row per kind of reading a robot gets, saying everything the simulator's
parts need to know of it, so that they iterate over the rows instead of spelling each kind.

A row names its `Readings` field, the robot-file section whose sensors give one value each (or
the fixed channels of a kind that is not a list of sensors), its dtype, the array of a step's
`SensorFrame` it is packed into (kinds that share an array lie in it in the registry's order,
robot after robot), the world kernel that computes it and the noise stage that perturbs it, the
recording's plot group and title, the viewer window's label, the c't-Sim packet the bridge
sends it in and how a Gymnasium observation holds it. `bots.readings.Readings` (a field per row)
and `bots.spec.RobotSpec`'s lists of sensors (a field per `section`) are made from the rows; the
World, the `SensorFrame`, the recorder, the export, the window, gym and the bridge read them. A
new kind is its row here (and, if no kernel computes it yet, its kernel): a test adds one so
(tests/test_sensor_kinds.py); another holds the packets to `sim.bridge.protocol`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class SensorKind:
    """One kind of reading (see the module)."""

    field: str
    """The `Readings` field (and the recording's and export's column name)."""
    section: str | None
    """The robot-file section (a `RobotSpec` field, a tuple of `sensor`s, made from it) with one
    value per sensor; None: `channels`."""
    channels: tuple[str, ...]
    """The fixed channels of a kind that is no list of sensors (a c't-Bot's)."""
    dtype: type
    frame: str | None
    """The `SensorFrame` array it is packed into; None: a general chassis's (`ChassisDrive.fill`)."""
    kernel: str
    """Where the world computes it (a dotted name under `sim.world`)."""
    noise: str | None
    """Where its noise enters (a dotted name under `sim.world`; None: it has none)."""
    group: str
    """The recording's plot it is drawn in (sensors/<group>/<robot>/<field>)."""
    title: str
    """That plot's title (the same for every kind of the group)."""
    window: str
    """Its line's label in the viewer window."""
    meaning: str = ""
    """What a `Readings` field of it holds, in which unit (its line of `Readings`' docstring)."""
    sensor: str | None = None
    """The class of one sensor of its `section` (a class of `bots.spec`)."""
    packet: str | None = None
    """The name of its c't-Sim packet in `sim.bridge.protocol` (None: not sent)."""
    wire: tuple[str, str] | None = None
    """The two channels its packet carries, in order, '-' before a negated one (None: its first two values)."""
    idle: tuple[int, int] = (0, 0)
    """What that packet carries for a sensor the robot lacks (of the two it sends): c't-Sim's reading of nothing."""
    scale: float = 1.0
    """Recorded and shown unit per SI unit (m -> mm, rad -> deg)."""
    needs: str | None = None
    """A `RobotSpec` attribute (dotted) that must not be None for it to have channels (a mouse)."""
    chassis_only: bool = False
    """Only a general chassis reads it."""
    per_wheel: bool = False
    """A general chassis has one channel per wheel (named after them) instead of its `channels`."""
    angle: bool = False
    """A wheel's angle: recorded and shown from the wheel's straight-ahead (`sim.views.chassis_view.steering_deflection`)."""
    rays: bool = False
    """A distance each of its sensors sees: the recording draws it as rays from the sensors."""
    observed: str | None = None
    """How a Gymnasium observation holds it (`sim.experiments.gym`): "distance" (m, nothing in
    range read as the sensor's `max_range`) or "fraction" (of `full_scale`); None: not at all."""
    full_scale: float = 1.0
    """Its highest value (the sensor's ADC's, 0-1023)."""

    def channels_of(self, spec: Any) -> tuple[str, ...]:
        """The channel names of a c't-Bot-like robot (`bots.spec.RobotSpec`): its section's sensor
        names, or the fixed channels (none where it lacks the device or only a chassis has it)."""
        if self.chassis_only or not self.present(spec):
            return ()
        if self.section is not None:
            return tuple(sensor.name for sensor in getattr(spec, self.section))
        return self.channels

    def present(self, spec: Any) -> bool:
        """Whether a robot (`bots.spec.RobotSpec`) has the device: a chassis for a general
        chassis's own kinds, and what it `needs`."""
        if self.chassis_only and spec.chassis is None:
            return False
        found = spec
        for name in self.needs.split(".") if self.needs else ():
            found = getattr(found, name)
            if found is None:
                return False
        return True

    def width(self, spec: Any) -> int:
        """How many values a robot's part of its `frame` array holds: one per sensor of its
        section, or its fixed channels (whether or not the robot has the device: a frame's rows
        are alike)."""
        return len(getattr(spec, self.section)) if self.section is not None else len(self.channels)


@dataclass(frozen=True)
class Frame:
    """One array of a step's `SensorFrame` (a kind's `frame`) and the World's row it is cut from
    (`World.sensor_rows`: `values` int64, `believed` float64, `tallies` int64); the arrays cut
    from one row lie in it in `FRAMES`' order."""

    name: str
    row: str


FRAMES = (Frame("floor", "values"), Frame("light", "values"), Frame("ir_raw", "values"), Frame("ir_distance", "believed"), Frame("tallies", "tallies"))
"""Every `SensorFrame` array, in the order the World packs its rows (its SENSORS table: floor, light, then IR sensors)."""


KINDS: tuple[SensorKind, ...] = (
    SensorKind("ir_raw", "ir", (), np.int64, "ir_raw", "kernels.sensing.read_ir", "kernels.sensing.ir_values", "ir_raw", "IR raw (ADC)", "IR raw",
               meaning="raw IR sensor values (ADC units, as c't-Sim), one per IR sensor of the robot", sensor="IRSensorSpec",
               packet="SENS_IR", idle=(100, 80)),  # (GP2D12 raw values with nothing in view: c't-Sim's curves beyond 85 cm)
    SensorKind("ir_distance", "ir", (), np.float64, "ir_distance", "kernels.sensing.read_ir", "kernels.sensing.ir_values", "ir_distance",
               "IR distance (mm)", "IR distance mm", meaning="distance the robot's firmware would infer from ir_raw (m); nan outside 0.1-0.8 m",
               sensor="IRSensorSpec", scale=1000.0, observed="distance", rays=True),
    SensorKind("line", "line", (), np.int64, "floor", "kernels.sensing.sample_floor", "kernels.noise.add_rounded", "floor",
               "floor: line and border (0 white, 1023 black)", "line   (0-1023)",
               meaning="CNY70 reflex sensors on the line, 0 (white) .. 1023 (black or hole)", sensor="FloorSensorSpec", packet="SENS_LINE",
               observed="fraction", full_scale=1023.0),
    SensorKind("border", "border", (), np.int64, "floor", "kernels.sensing.sample_floor", "kernels.noise.add_rounded", "floor",
               "floor: line and border (0 white, 1023 black)", "border (0-1023)",
               meaning="CNY70 reflex sensors at the border, 0 (white) .. 1023 (black or hole)", sensor="FloorSensorSpec", packet="SENS_BORDER",
               observed="fraction", full_scale=1023.0),
    SensorKind("light", "light", (), np.int64, "light", "kernels.sensing.sense_light", "kernels.noise.add_rounded", "light",
               "light (0 bright, 1023 dark)", "light  (0-1023)",
               meaning="light sensors, 0 (bright) .. 1023 (dark), c't-Sim's convention", sensor="LightSensorSpec", packet="SENS_LDR", idle=(1023, 1023),
               observed="fraction", full_scale=1023.0),
    SensorKind("encoder_ticks", None, ("left", "right"), np.int64, "tallies", "kernels.motion.plan", "kernels.noise.spurious_ticks",
               "encoders", "encoders (ticks per step)", "encoders ticks",
               meaning="signed ticks counted during the previous step, (left, right)", packet="SENS_ENC", per_wheel=True),
    SensorKind("mouse_counts", None, ("forward", "left"), np.int64, "tallies", "kernels.motion.measure", "kernels.noise.draw_step", "mouse",
               "mouse (counts per step: forward, left)", "mouse counts",
               meaning="signed counts during the previous step, (forward, left) in the sensor frame", needs="mouse",
               packet="SENS_MOUSE", wire=("-left", "forward")),  # (c't-Sim's dX sideways to the right, dY forward)
    SensorKind("mouse2_counts", None, ("mouse 2 forward", "mouse 2 left"), np.int64, None, "chassis_drive.ChassisDrive.fill", "chassis_drive.ChassisDrive.fill", "mouse",
               "mouse (counts per step: forward, left)", "mouse 2 counts",
               meaning="a general chassis's second mouse, as mouse_counts", needs="chassis.mouse2", chassis_only=True),
    SensorKind("steering", None, (), np.float64, None, "chassis_drive.ChassisDrive.fill", None, "steering", "steered from straight (deg)", "steered deg",
               meaning="each wheel's steering angle (its wheel plane's, rad) on a general chassis", scale=180.0 / math.pi, chassis_only=True, angle=True),
)
"""Every kind, in the recording's column order (and, within a shared `frame` array, the packing order)."""
BY_FIELD = {kind.field: kind for kind in KINDS}
FRAMED = tuple(kind for kind in KINDS if kind.frame is not None)
"""The kinds a step's `SensorFrame` holds (a general chassis's own are `ChassisDrive.fill`'s)."""


def groups() -> dict[str, tuple[str, tuple[str, ...]]]:
    """Recording plot -> (title, its kinds' fields), in the registry's order."""
    found: dict[str, tuple[str, tuple[str, ...]]] = {}
    for kind in KINDS:
        title, fields = found.get(kind.group, (kind.title, ()))
        found[kind.group] = (title, (*fields, kind.field))
    return found


def sections() -> dict[str, str]:
    """The robot-file sections of sensors, in the registry's order, each once -> the name of
    their sensor class (in `bots.spec`)."""
    return {kind.section: kind.sensor for kind in KINDS if kind.section is not None}
