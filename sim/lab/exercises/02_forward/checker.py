"""Checker of exercise 2: one step of eq 4 against the exact arc of the kinematics core."""

import math

import numpy as np

from sim.kinematics import (
    apply_increment,
    firmware_increment,
    integrate_arcs,
    wheel_arcs_to_arc,
    wrap_angle,
)
from sim.lab.checking import Outcome, close, diagnose, differing, fmt
from sim.lab.student import StudentError, numbers


def draw(rng, index, ranges):
    """Uniform draws; the first hidden scenario drives straight."""
    p = {k: float(rng.uniform(*v)) for k, v in ranges.items()}
    if index == 0:
        p["v_right"] = p["v_left"]
    return {"pose": [p["x"], p["y"], p["theta"]], **{k: p[k] for k in ("v_left", "v_right", "track", "dt")}}


def exact(pose, v_left, v_right, track, dt):
    """The exact arc (seed 002, eqs 1.7, 1.12): what eq 4 gives."""
    return integrate_arcs(np.asarray(pose, float), *wheel_arcs_to_arc([v_left * dt], [v_right * dt], track))[-1]


def mistakes(pose, v_left, v_right, track, dt):
    """What typical wrong steps return."""
    x, y, theta = pose
    s, alpha = (float(v) for v in wheel_arcs_to_arc(v_left * dt, v_right * dt, track))
    chord, mid = s * float(np.sinc(alpha / (2 * math.pi))), theta + alpha / 2  # sinc: sin(α/2)/(α/2)
    return {
        "euler": np.array([x + s * math.cos(theta), y + s * math.sin(theta), theta + alpha]),
        "euler_new": np.array([x + s * math.cos(theta + alpha), y + s * math.sin(theta + alpha), theta + alpha]),
        "end_heading": apply_increment(np.asarray(pose, float), firmware_increment(s, alpha)),
        "no_chord": np.array([x + s * math.cos(mid), y + s * math.sin(mid), theta + alpha]),
        "sin_cos": np.array([x + chord * math.sin(mid), y + chord * math.cos(mid), theta + alpha]),
        "old_heading": np.r_[exact(pose, v_left, v_right, track, dt)[:2], theta],
        "swapped": exact(pose, v_right, v_left, track, dt),
        "half_track": exact(pose, v_left, v_right, track / 2, dt),
        "degrees": np.r_[exact(pose, v_left, v_right, track, dt)[:2], theta + math.degrees(alpha)],
    }


def wrapped(got, want, tolerance):
    """Right but for a heading folded into one turn (the sheet asks for a continuous one)."""
    return close(got[:2], want[:2], tolerance) and abs(float(wrap_angle(got[2] - want[2]))) <= tolerance


def check(scenario, student):
    pose = [float(v) for v in scenario["pose"]]
    args = (scenario["v_left"], scenario["v_right"], scenario["track"], scenario["dt"])
    tolerance = scenario.tolerance["absolute"]
    steps = int(scenario.params.get("steps", 1))
    straight = args[0] == args[1]
    poses = [np.array(pose)]
    try:
        for _ in range(steps):
            poses.append(numbers(student.call("step", *poses[-1], *args), (3,), "step()"))
    except StudentError as err:
        if straight and err.exception == "ZeroDivisionError":
            return Outcome(fmt(exact(pose, *args)), err.detail, False, f"±{tolerance:g}", "straight")
        raise
    expected = [np.array(pose)]
    for _ in range(steps):
        expected.append(exact(expected[-1], *args))
    got, want = poses[-1], expected[-1]
    times = np.arange(steps + 1) * args[3]
    tracks = {"truth": (times, np.array(expected)), "yours": (times, np.array(poses))} if steps > 1 else None
    if close(got, want, tolerance * steps):
        return Outcome(fmt(want), fmt(got), True, f"±{tolerance * steps:g}", tracks=tracks)
    hint = "wrapped" if wrapped(got, want, tolerance * steps) else diagnose(poses[1], mistakes(pose, *args), tolerance)
    return Outcome(*differing(want, got), False, f"±{tolerance * steps:g}", hint, tracks=tracks)
