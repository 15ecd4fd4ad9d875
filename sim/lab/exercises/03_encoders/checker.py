"""Checker of exercise 3: the student's encoder estimator in a run, against the shipped exact-arc
encoder odometry fed the same ticks; wrong answers are matched against typical mistakes replayed
on the recorded readings."""

import math

import numpy as np

from bots.ctbot import CTBOT
from bots.odometry import EncoderOdometry, FirmwareOdometry, Geometry
from sim.lab.runs import check_estimator, robot


def draw(rng, index, ranges):
    """Another robot and four segments of 1-3 s with rim speeds up to 0.2 m/s."""
    params = {k: float(rng.uniform(*v)) for k, v in ranges.items()}
    params["segments"] = [[float(rng.uniform(1, 3)), *map(float, rng.uniform(-0.2, 0.2, 2))] for _ in range(4)]
    return params


class Euler(EncoderOdometry):
    """Each step along the old heading."""

    def update(self, readings):
        s, alpha = self.arc(readings)
        x, y, theta = self.pose
        self.pose = np.array([x + s * math.cos(theta), y + s * math.sin(theta), theta + alpha])


class Swapped(EncoderOdometry):
    def arc(self, readings):
        s, alpha = super().arc(readings)
        return s, -alpha


def mistakes(spec):
    return {
        "euler": Euler(),
        "end_heading": FirmwareOdometry(),
        "swapped": Swapped(),
        "hardcoded": EncoderOdometry(Geometry.nominal(CTBOT)),
        "radius": EncoderOdometry(Geometry((spec.wheel_radius,) * 2, spec.track_width)),
    }


def check(scenario, student):
    spec = robot(scenario.params)
    return check_estimator(scenario, spec, student, EncoderOdometry(), mistakes(spec))
