"""Checker of exercise 2: one step of eq 4 against the exact arc of the kinematics core; a
student's step is compared with what each typical mistake returns, in every scenario, so that
the hint names the mistake that explains all of them."""

import math

import numpy as np

from sim.kinematics import integrate_arcs, wheel_arcs_to_arc, wrap_angle
from sim.lab.checking import Outcome, close, differing, fmt
from sim.lab.student import StudentError, numbers

NEARLY = 1e-4
"""Relative difference of the wheel speeds in the nearly straight and nearly in-place draws: the
turn is far too small to see on a coarse plot, yet a straight-line shortcut is off by more than
the tolerance."""


def draw(rng, index, ranges):
    """Uniform draws; the first hidden scenario drives straight, the second nearly straight, the
    third nearly on the spot (a step that treats them as the special cases is caught) and the
    fourth turns right driving forward."""
    p = {k: float(rng.uniform(*v)) for k, v in ranges.items()}
    if index == 0:
        p["v_right"] = p["v_left"]
    elif index == 1:
        p["v_right"] = p["v_left"] * (1 + NEARLY)
    elif index == 2:
        p["v_right"] = -p["v_left"] * (1 + NEARLY)
    elif index == 3:  # a right turn driving forward (R < 0): the public examples turn left
        p["v_right"], p["v_left"] = sorted((abs(p["v_left"]), abs(p["v_right"])))
    return {"pose": [p["x"], p["y"], p["theta"]], **{k: p[k] for k in ("v_left", "v_right", "track", "dt")}}


def exact(pose, v_left, v_right, track, dt):
    """The exact arc (seed 002, eqs 1.7, 1.12): what eq 4 gives."""
    return integrate_arcs(np.asarray(pose, float), *wheel_arcs_to_arc([v_left * dt], [v_right * dt], track))[-1]


def _laid(pose, length, alpha, along, sine_first=False):
    """The pose moved by `length` along heading θ + `along`, turned by `alpha` (sine and cosine
    swapped if `sine_first`)."""
    x, y, theta = pose
    c, s = math.cos(theta + along), math.sin(theta + along)
    if sine_first:
        c, s = s, c
    return np.array([x + length * c, y + length * s, theta + alpha])


def _about(pose, icc, angle, alpha):
    """The pose rotated by `angle` about the point `icc`, its heading turned by `alpha`."""
    x, y, theta = pose
    c, s = math.cos(angle), math.sin(angle)
    return np.array([c * (x - icc[0]) - s * (y - icc[1]) + icc[0], s * (x - icc[0]) + c * (y - icc[1]) + icc[1], theta + alpha])


def mistakes(pose, v_left, v_right, track, dt):
    """What typical wrong steps return (hint key -> pose), each written as a student would."""
    x, y, theta = pose
    v, omega = (v_left + v_right) / 2, (v_right - v_left) / track
    s, alpha = v * dt, omega * dt
    chord = s * float(np.sinc(alpha / (2 * math.pi)))  # sinc: sin(α/2)/(α/2)
    right = exact(pose, v_left, v_right, track, dt)
    turning = v_left != v_right
    radius = v / omega if turning else math.inf
    icc = (x - radius * math.sin(theta), y + radius * math.cos(theta)) if turning else (math.nan, math.nan)
    found = {
        "euler": _laid(pose, s, alpha, 0.0),
        "euler_new": _laid(pose, s, alpha, alpha),
        "end_heading": _laid(pose, chord, alpha, alpha),
        "euler_chord": _laid(pose, chord, alpha, 0.0),
        "no_chord": _laid(pose, s, alpha, alpha / 2),
        "sinc_full": _laid(pose, s * float(np.sinc(alpha / math.pi)), alpha, alpha / 2),
        "sin_cos": _laid(pose, chord, alpha, alpha / 2, sine_first=True),
        "old_heading": np.r_[right[:2], theta],
        "heading_sign": np.r_[right[:2], theta - alpha],
        "degrees": np.r_[right[:2], theta + math.degrees(alpha)],
        "swapped": exact(pose, v_right, v_left, track, dt),
        "half_track": exact(pose, v_left, v_right, track / 2, dt),
        "double_track": exact(pose, v_left, v_right, track * 2, dt),
        "omega_no_track": exact(pose, v_left, v_right, 1.0, dt),
        "v_sum": exact(pose, 2 * v_left, 2 * v_right, 2 * track, dt),
        "v_diff": _laid(pose, (v_right - v_left) / 2 * dt * float(np.sinc(alpha / (2 * math.pi))), alpha, alpha / 2),
        "dt_ignored": exact(pose, v_left, v_right, track, 1.0),
        "half_dt": exact(pose, v_left, v_right, track, dt / 2),
        "double_dt": exact(pose, v_left, v_right, track, dt * 2),
        "y_sign": np.array([right[0], 2 * y - right[1], right[2]]),
        "millimetres": np.array([x + 1000 * (right[0] - x), y + 1000 * (right[1] - y), right[2]]),
        "order": right[[2, 0, 1]],
        "increment": right - np.asarray(pose, float),
        "theta_degrees": np.r_[exact([x, y, math.radians(theta)], v_left, v_right, track, dt)[:2], theta + alpha],
    }
    turns = {  # mistakes of the turning branch: a straight step never reaches them
        "icc_side": lambda: _about(pose, (x + radius * math.sin(theta), y - radius * math.cos(theta)), alpha, alpha),
        "negative_rotation": lambda: _about(pose, icc, -alpha, alpha),
        "radius_no_2": lambda: _about(pose, (x - 2 * radius * math.sin(theta), y + 2 * radius * math.cos(theta)), alpha, alpha),
        "radius_abs": lambda: _about(pose, (x - abs(radius) * math.sin(theta), y + abs(radius) * math.cos(theta)), alpha, alpha),
        "no_icc_add": lambda: _about(pose, icc, alpha, alpha) - np.array([icc[0], icc[1], 0.0]),
    }
    straights = {  # mistakes of the straight-line branch: a turning step never reaches them
        "straight_frozen": lambda: np.asarray(pose, float),
        "straight_no_dt": lambda: _laid(pose, v, 0.0, 0.0),
        "straight_sin_cos": lambda: _laid(pose, s, 0.0, 0.0, sine_first=True),
    }
    found |= {key: make() if turning else right for key, make in turns.items()}
    found |= {key: right if turning else make() for key, make in straights.items()}
    return found


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
    matches = tuple(key for key, value in mistakes(pose, *args).items() if close(poses[1], value, tolerance))
    if close(got, want, tolerance * steps):
        return Outcome(fmt(want), fmt(got), True, f"±{tolerance * steps:g}", tracks=tracks, matches=matches)
    hint = "wrapped" if wrapped(got, want, tolerance * steps) else None
    return Outcome(*differing(want, got), False, f"±{tolerance * steps:g}", hint, tracks=tracks, matches=matches)
