"""Checker of exercise 6: the robot (with the scenario's hidden diameter and track errors) drives
UMBmark's square both ways by its own odometry; the student computes the corrected geometry from
the return errors, which is compared with sim.analysis.umbmark's and then driven again to show
the improvement."""

import math

import numpy as np

from bots.odometry.base import Geometry
from sim.analysis.umbmark import corrected_geometry, systematic_errors, umbmark
from sim.lab.checking import Outcome, close, diagnose, fmt
from sim.lab.runs import robot
from sim.lab.student import numbers

PLAUSIBLE = 0.2
"""Relative change of a size beyond which the corrected robot is not driven (its square may never close)."""


def draw(rng, index, ranges):
    return {"diameter_error": [float(v) for v in rng.uniform(*ranges["diameter_error"], 2)],
            "track_error": float(rng.uniform(*ranges["track_error"])), "side": float(ranges["side"])}  # fmt: skip


def geometry(values) -> Geometry:
    return Geometry((float(values[0]), float(values[1])), float(values[2]))


def flat(g: Geometry) -> np.ndarray:
    return np.array([*g.wheel_diameters, g.track_width])


def mistakes(before, believed: Geometry) -> dict:
    """What typical wrong calibrations return, from the same centres of gravity."""
    side, track = before.side, believed.track_width
    _, _, e_d, e_b = systematic_errors(before.cg_ccw, before.cg_cw, side, track)
    alpha, beta = math.degrees(before.alpha), math.degrees(before.beta)
    radius = (side / 2) / math.sin(beta / 2)
    return {
        "swapped": flat(corrected_geometry(believed, e_d, e_b)),
        "inverted": flat(corrected_geometry(believed, 1 / before.e_d, 1 / before.e_b)),
        "track_only": flat(corrected_geometry(believed, 1.0, before.e_b)),
        "degrees": flat(corrected_geometry(believed, (radius + track / 2) / (radius - track / 2), 90 / (90 - alpha))),
    }


def check(scenario, student):
    spec = robot({}).with_changes(encoders={"diameter_error": tuple(scenario["diameter_error"]), "track_error": scenario["track_error"]})
    side, believed = float(scenario["side"]), Geometry.nominal(spec)
    before = umbmark(spec, side, runs=1, seed=scenario.seed)
    args = (before.errors_cw.tolist(), before.errors_ccw.tolist(), side, list(believed.wheel_diameters), believed.track_width)
    got = numbers(student.call("corrections", *args), (3,), "corrections()")
    want = flat(before.corrected)
    tolerance = scenario.tolerance["absolute"]
    shown = f"{fmt(got)} E_max {before.max_error * 1000:.0f}"
    improved = False
    if np.all(np.abs(got / flat(believed) - 1) < PLAUSIBLE):
        after = umbmark(spec, side, runs=1, geometry=geometry(got), seed=scenario.seed)
        improved = after.max_error < before.max_error
        shown += f"→{after.max_error * 1000:.0f}"
    shown += " mm"
    passed = close(got, want, tolerance) and improved
    hint = None if passed else diagnose(got, mistakes(before, believed), tolerance)
    return Outcome(f"{fmt(want)}; smaller E_max", shown, passed, f"±{tolerance:g} m", hint)
