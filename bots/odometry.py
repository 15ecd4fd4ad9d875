"""Odometry estimators: what a robot believes about its pose, from its own readings only.

An estimator is reset with the robot's description and its start pose, then takes each step's
readings and exposes `pose` (x, y m, heading rad, continuous). The comparison against ground truth
happens in the run loop's consumers (`sim.analysis.metrics`), never here.

Every estimator turns one step's readings into an arc (centre arc length s, heading change alpha)
and lays it down either exactly (chord along the mid-angle, seed 002 eqs 1.7, 1.12) or as the
c't-Bot firmware does (chord along the end heading, ctsim-reference §5).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal, Protocol

import numpy as np

from bots.chassis_odometry import chassis_estimators
from bots.spec import RobotSpec
from sim.kinematics import MouseEstimator, advance
from sim.kinematics.mouse import counts_per_metre
from sim.world.readings import Readings

G_POS = 0.5
"""The c't-Bot firmware's weight of the encoder pose against the mouse pose (bot-local.h:108)."""
TURN_MEMORY = 0.25
"""Time constant (s) over which the fused estimator forgets the mouse's and the encoders' rotation
disagreeing: long enough to see a slide build up, short enough that a wrong track width (a few
per cent of the turning) never adds up to the band."""
TURN_SCALE_ERROR = 0.05
"""Relative disagreement of the two rotations allowed for believed wheel and track sizes that are
off (UMBmark finds a few per cent)."""
NOISE_COUNTS = 3.0
"""Mouse noise (counts) allowed over the memory: 0.2-0.5 counts per step add up to 1-2.5 counts."""


class Estimator(Protocol):
    """Dead reckoning from readings."""

    name: str
    pose: np.ndarray

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None: ...
    def update(self, readings: Readings) -> None: ...


@dataclass(frozen=True)
class Geometry:
    """What the robot's own code believes about its drive (m): the nominal values unless a
    calibration such as UMBmark corrected them."""

    wheel_diameters: tuple[float, float]
    track_width: float

    @classmethod
    def nominal(cls, robot: RobotSpec) -> Geometry:
        """The geometry the robot description states."""
        return cls((robot.wheel_diameter, robot.wheel_diameter), robot.track_width)


class _ArcOdometry:
    """Shared dead reckoning: `arc(readings)` gives (s, alpha) for the step, laid by `advance`."""

    name = "arc"
    end_heading = False

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        self.robot = robot
        self.pose = np.asarray(pose, dtype=np.float64).copy()

    def arc(self, readings: Readings) -> tuple[float, float]:
        raise NotImplementedError

    def update(self, readings: Readings) -> None:
        self.pose = advance(self.pose, *self.arc(readings), self.end_heading)


class EncoderOdometry(_ArcOdometry):
    """Wheel encoders through the exact arc: ticks -> wheel arcs -> pose increment (eqs 1.3, 1.12).

    geometry: the believed wheel diameters and track; None = the robot's nominal ones."""

    name = "encoders"

    def __init__(self, geometry: Geometry | None = None):
        self.geometry = geometry

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        super().reset(robot, pose)
        believed = self.geometry or Geometry.nominal(robot)
        self.track = believed.track_width
        # metres of rim per tick, per wheel
        self.metres_per_tick = tuple(math.pi * d / robot.encoders.ticks_per_rev for d in believed.wheel_diameters)

    def arc(self, readings: Readings) -> tuple[float, float]:
        # `wheel_arcs_to_arc` in plain floats (the same operations): numpy's per-call cost on
        # two numbers is most of an estimator's step
        left, right = readings.encoder_ticks.tolist()
        s_left, s_right = left * self.metres_per_tick[0], right * self.metres_per_tick[1]
        return 0.5 * (s_left + s_right), (s_right - s_left) / self.track


class FirmwareOdometry(EncoderOdometry):
    """The c't-Bot firmware's encoder odometry (sensor.c:297-345): the same arc, but the chord is
    laid along the heading after the turn, a lateral error of s_hat*sin(alpha/2) per step."""

    name = "firmware"
    end_heading = True


class MouseOdometry(_ArcOdometry):
    """The optical mouse through the inverse model (seed 002 §2.1): alpha = lateral/m_x,
    s = forward + alpha*m_y, at the dpi the robot believes (the nominal one)."""

    name = "mouse"

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        if robot.mouse is None:
            raise ValueError(f"robot {robot.name!r} has no mouse sensor: mouse odometry does not apply")
        super().reset(robot, pose)
        self.model = MouseEstimator(tuple(robot.mouse.mount), robot.mouse.dpi)
        self.mount = tuple(float(m) for m in self.model.mount)
        self.per_metre = float(counts_per_metre(self.model.dpi))

    def arc(self, readings: Readings) -> tuple[float, float]:
        # `MouseEstimator.arc` in plain floats (the same operations), as `EncoderOdometry.arc`
        forward, lateral = readings.mouse_counts.tolist()
        alpha = lateral / self.per_metre / self.mount[0]
        return forward / self.per_metre + alpha * self.mount[1], alpha


class FusedOdometry(_ArcOdometry):
    """Encoders and mouse together.

    rule "blend": the c't-Bot's coupled estimate (MEASURE_COUPLED_AVAILABLE): the encoder and the
    mouse poses, each dead-reckoned on its own, averaged with weight G_POS on the encoders
    (name "fused_blend").

    rule "slip" (default, name "fused"): heading change from the mouse, which sees the body turn whatever the
    wheels do, is blind to wheel diameter and track errors, and resolves 1 count / m_x
    (4.2 mrad on the c't-Bot) without accumulating, against 1 tick / track (30 mrad) for the
    encoders. Distance from the encoders, except where they slipped: with the remainder carried,
    the running totals of encoder and mouse distance each lag the truth by less than one count, so
    without slip their difference stays below `tolerance` = one tick of rim + one mouse count
    (scaled by 1 + |m_y|/|m_x| for the forward term alpha*m_y). Whatever the encoders add beyond
    that band is slip and is dropped: the fused distance follows the encoders but never strays
    more than `tolerance` from the mouse's. A robot pushing against a wall therefore drifts at
    most `tolerance`. Limit: a mouse that reads zero while the robot moves (lifted, over a hole,
    too fast) looks like slip too.

    Wall contact: a robot sliding sideways along a wall moves its single mouse sideways, which the
    mouse can only read as rotation (1 mm of slide = 3.8 degrees on the c't-Bot). So the rotation
    is checked against the encoders': their disagreement, summed with a memory of TURN_MEMORY,
    stays without a slide within `turn_tolerance` = twice the two quantisation bands (2 * (1 tick /
    track + 1 count / |m_x|): a forgetting sum of lags can reach twice the lag), 3 counts of mouse
    noise and TURN_SCALE_ERROR of the recent turning. While it is beyond, the mouse is sliding: the
    heading follows the encoders, and what the mouse added before the slide was seen is taken back
    (the disagreement fades below the band within TURN_MEMORY * ln(size / band) after the slide). `contact_steps` counts those steps. Limit: a slide under
    about 1 mm goes unnoticed, and wheels spinning on the spot while the body does not turn would
    be read as a slide of the mouse.
    """

    def __init__(self, rule: Literal["slip", "blend"] = "slip", geometry: Geometry | None = None, weight: float = G_POS):
        if rule not in ("slip", "blend"):
            raise ValueError(f"fusion rule must be 'slip' or 'blend', got {rule!r}")
        self.rule = rule
        self.name = "fused" if rule == "slip" else "fused_blend"
        self.weight = weight
        self.encoders = EncoderOdometry(geometry)
        self.mouse = MouseOdometry()

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        super().reset(robot, pose)
        self.encoders.reset(robot, pose)
        self.mouse.reset(robot, pose)
        mount_x, mount_y = robot.mouse.mount
        count = 1.0 / counts_per_metre(robot.mouse.dpi)
        self.tolerance = float(max(self.encoders.metres_per_tick) + count * (1.0 + abs(mount_y) / abs(mount_x)))
        self.disagreement = 0.0
        self.turn_tolerance = 2.0 * (max(self.encoders.metres_per_tick) / self.encoders.track + count / abs(mount_x))
        self.turn_tolerance += NOISE_COUNTS * count / abs(mount_x)
        self.turn_disagreement = 0.0  # mouse minus encoder rotation, forgetting (rad)
        self.taken = 0.0  # the part of it the heading took from the mouse (rad)
        self.turning = 0.0  # encoder rotation in the same memory (rad)
        self.time: float | None = None
        self.contact_steps = 0

    def arc(self, readings: Readings) -> tuple[float, float]:
        s_enc, alpha_enc = self.encoders.arc(readings)
        s_mouse, alpha_mouse = self.mouse.arc(readings)
        total = self.disagreement + s_enc - s_mouse
        self.disagreement = min(max(total, -self.tolerance), self.tolerance)
        return s_enc - (total - self.disagreement), self._rotation(alpha_mouse, alpha_enc, readings.time)

    def _rotation(self, alpha_mouse: float, alpha_enc: float, time: float) -> float:
        """The mouse's rotation, or the encoders' while the mouse slides sideways (wall contact)."""
        keep = 1.0 if self.time is None else math.exp(-max(time - self.time, 0.0) / TURN_MEMORY)
        self.time = time
        self.turning = self.turning * keep + abs(alpha_enc)
        self.turn_disagreement = self.turn_disagreement * keep + alpha_mouse - alpha_enc
        self.taken = self.taken * keep
        if abs(self.turn_disagreement) <= self.turn_tolerance + TURN_SCALE_ERROR * self.turning:
            self.taken += alpha_mouse - alpha_enc
            return alpha_mouse
        self.contact_steps += 1
        taken, self.taken = self.taken, 0.0
        return alpha_enc - taken

    def update(self, readings: Readings) -> None:
        if self.rule == "slip":
            super().update(readings)
            return
        self.encoders.update(readings)
        self.mouse.update(readings)
        self.pose = self.weight * self.encoders.pose + (1.0 - self.weight) * self.mouse.pose


def _mouse_applies(robot: RobotSpec) -> bool:
    """A mouse that can see rotation: present and off the wheel axle line."""
    return robot.mouse is not None and math.isfinite(robot.mouse.mount[0]) and abs(robot.mouse.mount[0]) >= MouseEstimator.min_lever


def default_estimators(robot: RobotSpec, geometry: Geometry | None = None) -> list[Estimator]:
    """The estimators a run compares by default for this robot: encoders and firmware always,
    mouse and fused where the robot has a mouse that can see rotation; for a general chassis, its
    encoder and mouse estimators (`bots.chassis_odometry`)."""
    if robot.chassis is not None:
        return chassis_estimators(robot)
    chosen: list[Estimator] = [EncoderOdometry(geometry), FirmwareOdometry(geometry)]
    if _mouse_applies(robot):
        chosen += [MouseOdometry(), FusedOdometry(geometry=geometry)]
    return chosen
