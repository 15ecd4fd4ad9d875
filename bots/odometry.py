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
from bots.odometry_steps import (
    DISTANCE_MEMORY,
    GATE,
    HAS_MOUSE,
    MEMORY,
    MOUNT_X,
    MOUNT_Y,
    MOUSE_VAR,
    PARAMS,
    PER_METRE,
    SLIP_VAR,
    STATE,
    TICK_LEFT,
    TICK_RIGHT,
    TICK_VAR_LEFT,
    TICK_VAR_RIGHT,
    TIME,
    TOLERANCE,
    TRACK,
    TURN_TOLERANCE,
    encoder_step,
    fused_step,
    mouse_step,
    mouse_terms,
    pose_covariance,
    wheel_terms,
)
from bots.spec import RobotSpec
from bots.uncertainty import COVARIANCE_FIELDS, ERRORS, Belief, square
from sim.kinematics import MouseEstimator, advance
from sim.kinematics.mouse import counts_per_metre
from sim.world.readings import Readings

G_POS = 0.5
"""The c't-Bot firmware's weight of the encoder pose against the mouse pose (bot-local.h:108)."""
TURN_MEMORY = 0.25
"""Time constant (s) over which the fused estimator forgets the mouse's and the encoders' rotation
disagreeing: long enough to see a slide build up, short enough that a wrong track width (a few
per cent of the turning) never adds up to the band."""
SLIP_MEMORY = 0.1
"""Metres of the mouse's path over which the fused estimator forgets the encoders' and the
mouse's distance disagreeing: a robot standing still forgets nothing (a wheel spinning against a
wall stays slip), one driving sees a slide of a few millimetres among 10 cm."""
GATE_SIGMAS = 5.0
"""Standard deviations of the random noise summed over the memory, and of the calibration still
unknown (per metre driven, per radian turned), that the two sensors may disagree by before the
fused estimator calls it slip or a slide: at 3 the detectors, whose sums are correlated from step
to step, fired often enough on noise alone to make the fused heading worse than the mouse's."""
NOISE_COUNTS = 3.0
"""Mouse noise (counts) allowed over the memory: 0.2-0.5 counts per step add up to 1-2.5 counts."""


class Estimator(Protocol):
    """Dead reckoning from readings: `reset` at the start pose, `update` every step; `pose`
    (3,) x, y m, heading rad. Optional: `covariance`, the (3, 3) covariance of the pose's error
    (m², m·rad, rad²) after the last update; without it, the estimate is reported without one."""

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


def parameters(robot: RobotSpec, geometry: Geometry | None = None) -> np.ndarray:
    """The robot's row of `bots.odometry_steps` parameters (PARAMS,): what its estimators
    believe of its drive (`geometry`, None: nominal), its mouse and its noise (`Belief.of`)."""
    p = np.zeros(PARAMS)
    believed = geometry or Geometry.nominal(robot)
    p[TICK_LEFT], p[TICK_RIGHT] = (math.pi * d / robot.encoders.ticks_per_rev for d in believed.wheel_diameters)
    p[TRACK] = believed.track_width
    belief = Belief.of(robot)
    p[SLIP_VAR] = belief.slip_var
    # a metre rolled is 1/tick ticks, each one off by a tick with probability tick_rate: m² per metre
    p[TICK_VAR_LEFT], p[TICK_VAR_RIGHT] = belief.tick_rate * p[TICK_LEFT], belief.tick_rate * p[TICK_RIGHT]
    if _mouse_applies(robot):
        mount_x, mount_y = (float(m) for m in robot.mouse.mount)
        p[PER_METRE], p[MOUNT_X], p[MOUNT_Y] = float(counts_per_metre(robot.mouse.dpi)), mount_x, mount_y
        count = 1.0 / p[PER_METRE]
        # the fused estimator's detectors (see FusedOdometry)
        p[TOLERANCE] = max(p[TICK_LEFT], p[TICK_RIGHT]) + count * (1.0 + abs(mount_y) / abs(mount_x))
        p[TURN_TOLERANCE] = 2.0 * (max(p[TICK_LEFT], p[TICK_RIGHT]) / p[TRACK] + count / abs(mount_x)) + NOISE_COUNTS * count / abs(mount_x)
        p[MEMORY], p[GATE], p[DISTANCE_MEMORY] = TURN_MEMORY, GATE_SIGMAS, SLIP_MEMORY
        p[MOUSE_VAR] = belief.mouse_var
        p[HAS_MOUSE] = 1.0
    return p


def quantisation_lag(p: np.ndarray, mouse: bool) -> np.ndarray:
    """(2, 2) covariance of the (s, alpha) lag of carried counts (each uniform over one count):
    the encoders' or the mouse's."""
    lag, jac = np.zeros((2, 2)), np.zeros((2, ERRORS))
    if mouse:
        mouse_terms(0.0, 0.0, p[MOUNT_X], p[MOUNT_Y], 1.0 / (12.0 * p[PER_METRE] ** 2), jac, lag)
    else:
        wheel_terms(0.0, 0.0, 0.0, p[TRACK], p[TICK_LEFT] ** 2 / 12.0, p[TICK_RIGHT] ** 2 / 12.0, jac, lag)
    return lag


class _ArcOdometry:
    """Shared dead reckoning: `step(readings)` gives (s, alpha) for the step, laid by `advance`,
    and propagates the error covariance `errors` (`bots.uncertainty`) in the same compiled step
    (`bots.odometry_steps`); `lag` is the quantisation lag reported beside it."""

    name = "arc"
    end_heading = False
    uses_mouse = False

    def __init__(self, geometry: Geometry | None = None):
        self.geometry = geometry

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        if self.uses_mouse and not _mouse_applies(robot):
            raise ValueError(f"robot {robot.name!r} has no mouse sensor that sees rotation: {self.name} odometry does not apply")
        self.robot = robot
        self.pose = np.asarray(pose, dtype=np.float64).copy()
        self.params = parameters(robot, self.geometry)
        self.errors = Belief.of(robot).prior()
        self.lag = quantisation_lag(self.params, self.uses_mouse)
        self._entries = np.zeros(len(COVARIANCE_FIELDS))

    def step(self, readings: Readings) -> tuple[float, float]:
        raise NotImplementedError

    def update(self, readings: Readings) -> None:
        s, alpha = self.step(readings)
        self.pose = advance(self.pose, s, alpha, self.end_heading)

    @property
    def covariance(self) -> np.ndarray:
        """(3, 3) covariance of the pose's error (m², m·rad, rad²): propagated plus the lag."""
        pose_covariance(self.errors, float(self.pose[2]), self.lag, self._entries)
        return square(self._entries)


class EncoderOdometry(_ArcOdometry):
    """Wheel encoders through the exact arc: ticks -> wheel arcs -> pose increment (eqs 1.3, 1.12).
    Covariance: each wheel's arc has variance (slip_var + tick_rate * tick) * |s| per step, and
    the wheel scales and track are unknown by their believed size (`bots.uncertainty`).

    geometry: the believed wheel diameters and track; None = the robot's nominal ones."""

    name = "encoders"

    def step(self, readings: Readings) -> tuple[float, float]:
        left, right = readings.encoder_ticks.tolist()
        return encoder_step(self.params, float(self.pose[2]), self.errors, float(left), float(right), self.end_heading)


class FirmwareOdometry(EncoderOdometry):
    """The c't-Bot firmware's encoder odometry (sensor.c:297-345): the same arc, but the chord is
    laid along the heading after the turn, a lateral error of s_hat*sin(alpha/2) per step.

    Not consistent by construction: its covariance is the encoders' noise laid along the end
    heading, and the firmware's own lateral error, a bias of its arithmetic rather than of a
    sensor, is not in it (its NEES grows with the turning)."""

    name = "firmware"
    end_heading = True


class MouseOdometry(_ArcOdometry):
    """The optical mouse through the inverse model (seed 002 §2.1): alpha = lateral/m_x,
    s = forward + alpha*m_y, at the dpi the robot believes (the nominal one). Covariance: each
    axis's reading has the mouse's count variance per step, and the resolution is unknown by its
    believed size (`bots.uncertainty`). Not modelled: a mouse too fast to track (reads zero)."""

    name = "mouse"
    uses_mouse = True

    def __init__(self) -> None:
        super().__init__()

    def step(self, readings: Readings) -> tuple[float, float]:
        forward, lateral = readings.mouse_counts.tolist()
        return mouse_step(self.params, float(self.pose[2]), self.errors, float(forward), float(lateral))


class FusedOdometry(_ArcOdometry):
    """Encoders and mouse together.

    rule "ekf" (default, name "fused"): an extended Kalman filter of the pose and the four
    calibration errors (`bots.odometry_steps.fused_step`): every step the encoders' and the
    mouse's increments, each corrected by the calibration estimated so far, are weighted by their
    information, and their disagreement updates the calibration. The mouse resolves 1 count / m_x
    (4.2 mrad on the c't-Bot) per step against 1 tick / track (30 mrad) for the encoders, so the
    heading follows the mouse and the encoders' distance counts as their ticks add up.

    Two detectors leave a sensor out where its model does not hold. Slip: with the remainder
    carried, the running totals of encoder and mouse distance each lag the truth by less than one
    count, so without slip their difference stays below `tolerance` = one tick of rim + one
    mouse count (scaled by 1 + |m_y|/|m_x| for the forward term alpha*m_y); where the encoders
    add more, they slipped, and their distance is left out that step (a robot pushing against a
    wall drifts at most `tolerance`). Limit: a mouse that reads zero while the robot
    moves (lifted, over a hole, too fast) looks like slip too.

    Wall contact: a robot sliding sideways along a wall moves its single mouse sideways, which the
    mouse can only read as rotation (1 mm of slide = 3.8 degrees on the c't-Bot). So the rotation
    is checked against the encoders': their disagreement, summed with a memory of TURN_MEMORY,
    stays without a slide within `turn_tolerance` = twice the two quantisation bands (2 * (1 tick /
    track + 1 count / |m_x|): a forgetting sum of lags can reach twice the lag), 3 counts of mouse
    noise and GATE_SIGMAS standard deviations of the calibration still unknown over the recent turning
    and driving. While it is beyond, the mouse is sliding: its
    rotation is left out, and what it added to the heading before the slide was seen is taken back
    (the disagreement fades below the band within TURN_MEMORY * ln(size / band) after the slide).
    `contact_steps` counts those steps. Limits: a slide under about 1 mm goes unnoticed, and the
    rotation taken back is not in the covariance.

    rule "blend": the c't-Bot's coupled estimate (MEASURE_COUPLED_AVAILABLE): the encoder and the
    mouse poses, each dead-reckoned on its own, averaged with weight G_POS on the encoders
    (name "fused_blend"), its covariance that of the same average of the two (their errors taken
    as independent).
    """

    uses_mouse = True

    def __init__(self, rule: Literal["ekf", "blend"] = "ekf", geometry: Geometry | None = None, weight: float = G_POS):
        if rule not in ("ekf", "blend"):
            raise ValueError(f"fusion rule must be 'ekf' or 'blend', got {rule!r}")
        super().__init__(geometry)
        self.rule = rule
        self.name = "fused" if rule == "ekf" else "fused_blend"
        self.weight = weight
        self.encoders = EncoderOdometry(geometry)
        self.mouse = MouseOdometry()

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        super().reset(robot, pose)
        self.encoders.reset(robot, pose)
        self.mouse.reset(robot, pose)
        self.tolerance, self.turn_tolerance = float(self.params[TOLERANCE]), float(self.params[TURN_TOLERANCE])
        self.state = np.zeros(STATE)
        self.state[TIME] = math.nan
        self.calibration = np.zeros(ERRORS)
        """The estimated calibration errors (entries LEFT_SCALE on of `bots.uncertainty`; relative)."""
        self.contact_steps = 0

    def update(self, readings: Readings) -> None:
        if self.rule == "blend":
            self.encoders.update(readings)
            self.mouse.update(readings)
            self.pose = self.weight * self.encoders.pose + (1.0 - self.weight) * self.mouse.pose
            return
        left, right = readings.encoder_ticks.tolist()
        forward, lateral = readings.mouse_counts.tolist()
        s, alpha, sliding = fused_step(self.params, self.state, self.pose, self.calibration, self.errors, self.lag,
                                       float(left), float(right), float(forward), float(lateral), float(readings.time))  # fmt: skip
        self.contact_steps += sliding
        self.pose = advance(self.pose, s, alpha, False)

    @property
    def covariance(self) -> np.ndarray:
        if self.rule == "ekf":
            return super().covariance
        w = self.weight
        return w * w * self.encoders.covariance + (1.0 - w) ** 2 * self.mouse.covariance


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
