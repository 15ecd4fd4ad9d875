"""The wheel encoders' odometry through the exact arc."""

from __future__ import annotations

from bots.odometry.base import ArcOdometry
from bots.odometry.steps import SIGMAS, encoder_step, sigma_encoders
from bots.readings import Readings


class EncoderOdometry(ArcOdometry):
    """Wheel encoders through the exact arc: ticks -> wheel arcs -> pose increment (eqs 1.3, 1.12).
    Covariance: each wheel's arc has variance (slip_var + tick_rate * tick) * |s| per step
    (first order), and the wheel scales and track are unknown by their believed size
    (`bots.uncertainty`), carried by six sigma points (`ArcOdometry`).

    geometry: the believed wheel diameters and track; None = the robot's nominal ones."""

    name = "encoders"
    sigma_count = SIGMAS

    def step(self, readings: Readings) -> tuple[float, float]:
        left, right = readings.encoder_ticks.tolist()
        sigma_encoders(self.params, self.sigmas, float(left), float(right), self.end_heading)
        return encoder_step(self.params, float(self.pose[2]), self.errors, float(left), float(right), self.end_heading, self.work)
