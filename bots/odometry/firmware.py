"""The c't-Bot firmware's encoder odometry: the encoders' arc laid along the end heading."""

from __future__ import annotations

from bots.odometry.encoder import EncoderOdometry


class FirmwareOdometry(EncoderOdometry):
    """The c't-Bot firmware's encoder odometry (sensor.c:297-345): the same arc, but the chord is
    laid along the heading after the turn, a lateral error of s_hat*sin(alpha/2) per step.

    Not consistent by construction: its covariance is the encoders' noise laid along the end
    heading, and the firmware's own lateral error, a bias of its arithmetic rather than of a
    sensor, is not in it (its NEES grows with the turning)."""

    name = "firmware"
    end_heading = True
    caveat = "not consistent by construction: its own lateral error (the chord laid along the end heading) is not in its covariance"
