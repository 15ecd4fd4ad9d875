"""Checker of exercise 1: R, ω and ICC against seed 003's eqs 2-3, with the special cases."""

import math

import numpy as np

from sim.lab.checking import Outcome, close, diagnose, differing, fmt
from sim.lab.student import StudentError, numbers


def draw(rng, index, ranges):
    """Uniform draws; the first two hidden scenarios are the special cases with new numbers, the
    third nearly straight (a coarse test for the straight case, |v_r − v_l| < ε, is caught)."""
    p = {k: float(rng.uniform(*v)) for k, v in ranges.items()}
    if index == 0:
        p["v_right"] = p["v_left"]
    elif index == 1:
        p["v_right"] = -p["v_left"]
    elif index == 2:
        p["v_right"] = p["v_left"] * (1 + 1e-3)  # R a few tens of metres: still exact to the tolerance
    return {"v_left": p["v_left"], "v_right": p["v_right"], "track": p["track"], "pose": [p["x"], p["y"], p["theta"]]}


def answer(v_left, v_right, track, pose, *, radius_factor=2.0, omega_sign=1.0, icc_sign=1.0, heading=None, omega_track=1.0):
    """(R, ω, icc_x, icc_y) by eqs 2-3; the keywords reproduce typical mistakes."""
    x, y, theta = pose
    theta = theta if heading is None else heading
    omega = omega_sign * (v_right - v_left) / (omega_track * track)
    if v_right == v_left:
        return np.array([math.inf, omega, math.inf, math.inf])
    radius = track * (v_left + v_right) / (radius_factor * (v_right - v_left))
    return np.array([radius, omega, x - icc_sign * radius * math.sin(theta), y + icc_sign * radius * math.cos(theta)])


def check(scenario, student):
    v_left, v_right, track, pose = scenario["v_left"], scenario["v_right"], scenario["track"], scenario["pose"]
    tolerance = scenario.tolerance["absolute"]
    expected = answer(v_left, v_right, track, pose)
    straight = v_left == v_right
    try:
        got = numbers(student.call("turn", v_left, v_right, track, *pose), (4,), "turn()", infinite=True)
    except StudentError as err:
        if straight and err.exception == "ZeroDivisionError":
            return Outcome(fmt(expected), err.detail, False, f"±{tolerance:g}", "straight")
        raise
    if close(got, expected, tolerance):
        return Outcome(fmt(expected), fmt(got), True, f"±{tolerance:g}")
    mistakes = {
        "swapped": answer(v_right, v_left, track, pose),
        "omega_sign": answer(v_left, v_right, track, pose, omega_sign=-1.0),
        "radius_factor": answer(v_left, v_right, track, pose, radius_factor=1.0),
        "icc_side": answer(v_left, v_right, track, pose, icc_sign=-1.0),
        "degrees": answer(v_left, v_right, track, pose, heading=math.radians(pose[2])),
        "half_track": answer(v_left, v_right, track, pose, omega_track=0.5),
    }
    hint = diagnose(got, mistakes, tolerance)
    radius_and_icc = close(got[[0, 2, 3]], expected[[0, 2, 3]], tolerance)
    if hint is None and straight:
        hint = "straight"
    elif hint is None and v_left == -v_right and not radius_and_icc:
        hint = "spot"
    return Outcome(*differing(expected, got), False, f"±{tolerance:g}", hint)
