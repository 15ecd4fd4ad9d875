"""Checker of exercise 3: the student's encoder estimator in a run, against the shipped exact-arc
encoder odometry fed the same ticks; wrong answers are matched against typical mistakes replayed
on the recorded readings."""

import dataclasses
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


class NoChord(EncoderOdometry):
    """The arc length laid along the mid-angle as if it were the chord."""

    def update(self, readings):
        s, alpha = self.arc(readings)
        x, y, theta = self.pose
        self.pose = np.array([x + s * math.cos(theta + alpha / 2), y + s * math.sin(theta + alpha / 2), theta + alpha])


class SinCos(EncoderOdometry):
    """The chord along the mid-angle with sine and cosine swapped."""

    def update(self, readings):
        s, alpha = self.arc(readings)
        chord = s * float(np.sinc(alpha / (2 * math.pi)))  # sin(alpha/2)/(alpha/2)
        x, y, theta = self.pose
        self.pose = np.array([x + chord * math.sin(theta + alpha / 2), y + chord * math.cos(theta + alpha / 2), theta + alpha])


class Swapped(EncoderOdometry):
    def arc(self, readings):
        s, alpha = super().arc(readings)
        return s, -alpha


class HalfTrack(EncoderOdometry):
    """alpha = (s_r - s_l)/(l/2)."""

    def arc(self, readings):
        s, alpha = super().arc(readings)
        return s, 2 * alpha


class Cumulative(EncoderOdometry):
    """encoder_ticks taken for running totals: each step uses the difference to the last reading."""

    def reset(self, robot, pose):
        super().reset(robot, pose)
        self.last = np.zeros(2)

    def update(self, readings):
        ticks = np.asarray(readings.encoder_ticks, dtype=np.float64)
        change, self.last = ticks - self.last, ticks
        super().update(dataclasses.replace(readings, encoder_ticks=change))


def mistakes(spec):
    diameter, track, ticks = spec.wheel_diameter, spec.track_width, spec.encoders.ticks_per_rev
    return {
        "euler": Euler(),
        "end_heading": FirmwareOdometry(),
        "no_chord": NoChord(),
        "sin_cos": SinCos(),
        "swapped": Swapped(),
        "half_track": HalfTrack(),
        "cumulative": Cumulative(),
        "hardcoded": EncoderOdometry(Geometry.nominal(CTBOT)),
        "radius": EncoderOdometry(Geometry((diameter / 2,) * 2, track)),
        "diameter_2pi": EncoderOdometry(Geometry((2 * diameter,) * 2, track)),
        "millimetres": EncoderOdometry(Geometry((1000 * diameter,) * 2, 1000 * track)),
        "ticks": EncoderOdometry(Geometry((ticks / math.pi,) * 2, track)),  # one metre of rim per tick
    }


def check(scenario, student):
    spec = robot(scenario.params)
    return check_estimator(scenario, spec, student, EncoderOdometry(), mistakes(spec))
