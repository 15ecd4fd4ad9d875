"""The wheel encoders' odometry through the exact arc."""

from __future__ import annotations

from bots.odometry.base import ArcOdometry
from bots.odometry.steps import encoder_step
from bots.readings import Readings


class EncoderOdometry(ArcOdometry):
    """Wheel encoders through the exact arc: ticks -> wheel arcs -> pose increment (eqs 1.3, 1.12).
    Covariance: each wheel's arc has variance (slip_var + tick_rate * tick) * |s| per step, and
    the wheel scales and track are unknown by their believed size (`bots.uncertainty`).

    geometry: the believed wheel diameters and track; None = the robot's nominal ones."""

    name = "encoders"

    def step(self, readings: Readings) -> tuple[float, float]:
        left, right = readings.encoder_ticks.tolist()
        return encoder_step(self.params, float(self.pose[2]), self.errors, float(left), float(right), self.end_heading, self.work)
