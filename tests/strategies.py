"""Shared hypothesis strategies and closed forms for the kinematics tests."""

from __future__ import annotations

import math
from functools import partial

import numpy as np
from hypothesis import strategies as st

from bots.ctbot import CTBOT

TRACK = CTBOT.track_width
WHEEL_RADIUS = CTBOT.wheel_diameter / 2
EPS = np.finfo(np.float64).eps
# subnormal lengths and angles are left to the no-NaN test: relative tolerances mean nothing there
floats = partial(st.floats, allow_subnormal=False)

# one step of wheel travel: up to 5 cm (the c't-Bot makes 4.5 mm per 10 ms step at full speed)
wheel_arc = floats(-0.05, 0.05)
track_width = floats(0.05, 0.5)
# heading changes of one step, straight and spin included, away from the 2*pi singularity of se2_log
alpha = st.one_of(st.just(0.0), floats(-1e-6, 1e-6), floats(-6.0, 6.0))
arc_length = st.one_of(st.just(0.0), floats(-1.0, 1.0))
angle = floats(-20.0, 20.0)
coordinate = floats(-100.0, 100.0)
pose = st.tuples(coordinate, coordinate, angle).map(np.array)
finite = st.floats(allow_nan=False, allow_infinity=False)


@st.composite
def mount_point(draw) -> np.ndarray:
    """A mouse mount point (m_x, m_y) off the axle line: |m_x| in [5 mm, 20 cm]."""
    m_x = draw(floats(0.005, 0.2)) * draw(st.sampled_from((-1.0, 1.0)))
    return np.array([m_x, draw(floats(-0.1, 0.1))])


def sinc(h: float) -> float:
    """sin(h)/h, 1 at 0 (reference for the tests, plain math)."""
    return math.sin(h) / h if h != 0.0 else 1.0


def analytic_pose(start: np.ndarray, v: float, omega: float, t: float) -> np.ndarray:
    """Pose after driving `t` s at constant (v, omega) from `start`, textbook closed form:
    a circle of radius R = v/omega about the ICC, a line for omega = 0."""
    x0, y0, th0 = start
    if omega == 0.0:
        return np.array([x0 + v * t * math.cos(th0), y0 + v * t * math.sin(th0), th0])
    th = th0 + omega * t
    radius = v / omega
    return np.array([x0 + radius * (math.sin(th) - math.sin(th0)), y0 - radius * (math.cos(th) - math.cos(th0)), th])


def rotate_about(point: np.ndarray, centre: np.ndarray, angle: float) -> np.ndarray:
    """`point` (..., 2) rotated by `angle` about `centre` (2,)."""
    c, s = math.cos(angle), math.sin(angle)
    d = np.asarray(point, dtype=np.float64) - centre
    return centre + np.stack((c * d[..., 0] - s * d[..., 1], s * d[..., 0] + c * d[..., 1]), axis=-1)
