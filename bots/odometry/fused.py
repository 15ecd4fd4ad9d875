"""Encoders and mouse together: an extended Kalman filter of the pose and the calibration, or the
c't-Bot's blend."""

from __future__ import annotations

from typing import Literal

import numpy as np

from bots.odometry.base import ArcOdometry, Geometry
from bots.odometry.encoder import EncoderOdometry
from bots.odometry.mouse import MouseOdometry
from bots.odometry.steps import (
    TOLERANCE,
    TURN_TOLERANCE,
    fused_step,
)
from bots.readings import Readings
from bots.spec import RobotSpec
from bots.uncertainty import ERRORS
from sim.kinematics import advance

G_POS = 0.5
"""The c't-Bot firmware's weight of the encoder pose against the mouse pose (bot-local.h:108)."""


class FusedOdometry(ArcOdometry):
    """Encoders and mouse together.

    rule "ekf" (default, name "fused"): an extended Kalman filter of the pose and the four
    calibration errors (`bots.odometry.steps.fused_step`): every step the encoders' and the
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
    `contact_steps` counts those steps. Limits: a slide under about 1 mm per TURN_MEMORY goes
    unnoticed here; a slower watch over SLIDE_WATCH_MEMORY (`bots.odometry.steps.watch_slides`)
    widens the heading's variance by what such a slide may have turned it, without moving the
    estimate (in the maze its mean NEES at the end is 3.95 over 40 runs, just above the interval,
    one run 45 degrees off after a slide; docs/odometry.md).

    Too cautious where the calibration is learnt: with systematic errors drawn from its belief,
    its errors spread a quarter to a half of what its covariance says (the quantisation taken as
    white noise in the update, see `bots.odometry.steps`, slows the covariance, not the estimate).

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
                                       float(left), float(right), float(forward), float(lateral), float(readings.time), self.work)  # fmt: skip
        self.contact_steps += sliding
        self.pose = advance(self.pose, s, alpha, False)

    @property
    def covariance(self) -> np.ndarray:
        if self.rule == "ekf":
            return super().covariance
        w = self.weight
        return w * w * self.encoders.covariance + (1.0 - w) ** 2 * self.mouse.covariance
