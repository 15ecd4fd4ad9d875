"""Checker of exercise 3: the student's encoder estimator in a run, against the shipped exact-arc
encoder odometry fed the same ticks; wrong answers are matched against typical mistakes replayed
on the recorded readings."""

import math

import numpy as np

from bots.ctbot import CTBOT
from bots.odometry import EncoderOdometry, FirmwareOdometry, Geometry
from sim.lab.artifacts import observers
from sim.lab.checking import Outcome, fmt
from sim.lab.runs import Collect, RemoteEstimator, Schedule, open_floor, replay, robot
from sim.run import RobotSetup, run


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
    spec, schedule, world = robot(scenario.params), Schedule(scenario["segments"]), open_floor()  # figures fit the path, not the floor
    collect = Collect()
    setup = RobotSetup(spec, schedule, "schedule", estimators=[EncoderOdometry(), RemoteEstimator(student, "Odometry")])
    result = run(world, [setup], schedule.duration + 0.5, seed=scenario.seed, observers=(collect, *observers(scenario)))
    log = result.robots[0]
    estimates = log.estimate_arrays()
    reference, yours = estimates["encoders"], estimates["yours"]
    tol_p, tol_h = scenario.tolerance["position"], scenario.tolerance["heading"]
    worst = float(np.hypot(*(yours[:, :2] - reference[:, :2]).T).max())
    heading = abs(yours[-1, 2] - reference[-1, 2])
    tracks = {"truth": (result.time, log.truth_array()), "reference": (result.time, reference), "yours": (result.time, yours)}
    tolerance = f"{tol_p:g} m, {tol_h:g} rad"
    if worst <= tol_p and heading <= tol_h:
        return Outcome(fmt(reference[-1]), fmt(yours[-1]), True, tolerance, tracks=tracks)
    start = log.truth_array()[0]
    hint = next((key for key, wrong in mistakes(spec).items()
                 if np.allclose(replay(wrong, spec, start, collect.samples), yours[-1], atol=tol_p, rtol=0)), None)  # fmt: skip
    return Outcome(fmt(reference[-1]), fmt(yours[-1]), False, tolerance, hint, {"error": worst}, tracks=tracks)
