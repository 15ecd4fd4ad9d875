"""Checker of exercise 3: the student's encoder estimator in a run, against the shipped exact-arc
encoder odometry fed the same ticks; every scenario's result is compared with typical mistakes
replayed on the recorded readings, so that the hint names the mistake that explains them all."""

import math

import numpy as np

from bots.ctbot import CTBOT
from bots.odometry.base import Geometry
from bots.odometry.encoder import EncoderOdometry
from sim.lab.runs import check_estimator, robot
from sim.world.step import DEFAULT_DT

NEARLY = 1e-3
"""Relative difference of the wheel speeds in the nearly straight and nearly in-place segments:
a heading change far too small to see on a plot, yet more than the tolerance at the end."""


def draw(rng, index, ranges):
    """Another robot and four segments of 1-3 s with rim speeds up to 0.2 m/s; the first hidden
    scenario drives nearly straight in its second segment and nearly on the spot in its third."""
    params = {k: float(rng.uniform(*v)) for k, v in ranges.items()}
    segments = [[float(rng.uniform(1, 3)), *map(float, rng.uniform(-0.2, 0.2, 2))] for _ in range(4)]
    if index == 0:
        segments[1][2] = segments[1][1] * (1 + NEARLY)
        segments[2][2] = -segments[2][1] * (1 + NEARLY)
    params["segments"] = segments
    return params


def chord_along(pose, s, alpha, along, sine_first=False):
    """The exact arc's chord s·sin(α/2)/(α/2) laid along θ + `along` (sine and cosine swapped if
    `sine_first`), the heading turned by α."""
    chord = s * float(np.sinc(alpha / (2 * math.pi)))
    return _laid(pose, chord, alpha, along, sine_first)


def _laid(pose, length, alpha, along, sine_first=False):
    x, y, theta = pose
    c, s = math.cos(theta + along), math.sin(theta + along)
    if sine_first:
        c, s = s, c
    return np.array([x + length * c, y + length * s, theta + alpha])


LAID = {
    "euler": lambda p, s, a: _laid(p, s, a, 0.0),
    "euler_new": lambda p, s, a: _laid(p, s, a, a),
    "end_heading": lambda p, s, a: chord_along(p, s, a, a),
    "euler_chord": lambda p, s, a: chord_along(p, s, a, 0.0),
    "no_chord": lambda p, s, a: _laid(p, s, a, a / 2),
    "sinc_full": lambda p, s, a: _laid(p, s * float(np.sinc(a / math.pi)), a, a / 2),
    "sin_cos": lambda p, s, a: chord_along(p, s, a, a / 2, sine_first=True),
    "mid_minus": lambda p, s, a: chord_along(p, s, a, -a / 2),
    "xy_swapped": lambda p, s, a: chord_along(p, s, a, a / 2)[[1, 0, 2]],
    "heading_frozen": lambda p, s, a: np.r_[chord_along(p, s, a, a / 2)[:2], p[2]],
    "heading_sign": lambda p, s, a: np.r_[chord_along(p, s, a, a / 2)[:2], p[2] - a],
    "degrees": lambda p, s, a: np.r_[chord_along(p, s, a, a / 2)[:2], p[2] + math.degrees(a)],
    "theta_degrees": lambda p, s, a: np.r_[chord_along(np.r_[p[:2], math.radians(p[2])], s, a, a / 2)[:2], p[2] + a],
    "y_sign": lambda p, s, a: chord_along(p, s, a, a / 2) * [1, -1, 1] + [0, 2 * p[1], 0],
    "frozen": lambda p, s, a: np.array(p, dtype=float),
}
"""Wrong ways to lay one step (pose, centre arc s, heading change α) -> the new pose."""
ARCS = {
    "swapped": lambda left, right, track: ((left + right) / 2, (left - right) / track),
    "half_track": lambda left, right, track: ((left + right) / 2, (right - left) / (track / 2)),
    "track_doubled": lambda left, right, track: ((left + right) / 2, (right - left) / (2 * track)),
    "s_sum": lambda left, right, track: (left + right, (right - left) / track),
    "alpha_no_track": lambda left, right, track: ((left + right) / 2, right - left),
    "left_only": lambda left, right, track: (left, (right - left) / track),
}
"""Wrong arcs from the wheels' arcs (m) and the track: (centre arc s, heading change α)."""


def _right_arcs(left, right, track):
    return (left + right) / 2, (right - left) / track


class Mistaken:
    """Encoder odometry as a student writes it (ticks -> wheel arcs -> the exact arc), with one
    step of it wrong: `geometry` the wheels and track believed, `arcs` the arc from the wheels'
    arcs, or `lay` the new pose."""

    name = "mistaken"

    def __init__(self, geometry=None, lay=None, arcs=_right_arcs):
        self.geometry, self.arcs = geometry, arcs
        self.lay = lay or (lambda p, s, a: chord_along(p, s, a, a / 2))

    def reset(self, robot, pose):
        believed = self.geometry or Geometry.nominal(robot)
        self.track = believed.track_width
        self.per_tick = tuple(math.pi * d / robot.encoders.ticks_per_rev for d in believed.wheel_diameters)
        self.pose = np.array(pose, dtype=float)

    def ticks(self, readings):
        return np.asarray(readings.encoder_ticks, dtype=np.float64)

    def update(self, readings):
        left, right = self.ticks(readings).tolist()
        s, alpha = self.arcs(left * self.per_tick[0], right * self.per_tick[1], self.track)
        self.pose = self.lay(self.pose, s, alpha)


class Cumulative(Mistaken):
    """encoder_ticks taken for running totals: each step uses the difference to the last reading."""

    def reset(self, robot, pose):
        super().reset(robot, pose)
        self.last = np.zeros(2)

    def ticks(self, readings):
        ticks = super().ticks(readings)
        change, self.last = ticks - self.last, ticks
        return change


def mistakes(spec):
    diameter, track, ticks = spec.wheel_diameter, spec.track_width, spec.encoders.ticks_per_rev
    scaled = lambda factor: Mistaken(Geometry((factor * diameter,) * 2, track))
    return {
        **{key: Mistaken(lay=lay) for key, lay in LAID.items()},
        **{key: Mistaken(arcs=arcs) for key, arcs in ARCS.items()},
        "cumulative": Cumulative(),
        "hardcoded": Mistaken(Geometry.nominal(CTBOT)),
        "radius": scaled(0.5),
        "diameter_2pi": scaled(2.0),
        "millimetres": Mistaken(Geometry((1000 * diameter,) * 2, 1000 * track)),
        "ticks": Mistaken(Geometry((ticks / math.pi,) * 2, track)),  # one metre of rim per tick
        "no_pi": scaled(1 / math.pi),
        "ticks_per_rev": scaled(ticks / 100),  # 100 ticks a turn taken, not the robot's
        "dt_scaled": scaled(DEFAULT_DT),  # ticks taken for ticks per second, times the step
    }


def check(scenario, student):
    spec = robot(scenario.params)
    return check_estimator(scenario, spec, student, EncoderOdometry(), mistakes(spec))
