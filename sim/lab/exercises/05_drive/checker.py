"""Checker of exercise 5: the student's controller drives through waypoints to a pose on a floor
with the scenario's obstacles; graded on the true final pose, the time it took, straying from the
path and collisions (the run's ground truth, which the controller never sees)."""

import math

import numpy as np

from sim.kinematics import wrap_angle
from sim.lab.artifacts import observers
from sim.lab.checking import Outcome
from sim.lab.runs import RemoteController, moved, path_distance, robot
from sim.run.loop import RobotSetup, run
from sim.world.spec import Start, Wall, WorldSpec

SPEED = 0.1
"""m/s a controller must average on the legs to finish within a hidden scenario's time."""


def draw(rng, index, ranges):
    """One leg (a pose) or two (a path), alternately; time for the legs at SPEED plus 2 s per turn."""
    points, heading = [np.zeros(2)], 0.0
    for _ in range(1 + index % 2):
        heading += float(rng.uniform(-2.0, 2.0))
        points.append(points[-1] + float(rng.uniform(*ranges["leg"])) * np.array([math.cos(heading), math.sin(heading)]))
    length = sum(float(np.hypot(*(b - a))) for a, b in zip(points, points[1:]))
    return {"waypoints": [p.tolist() for p in points[1:]], "heading": float(rng.uniform(*ranges["heading"])),
            "time": round(2.0 + length / SPEED + 2.0 * len(points), 1)}  # fmt: skip


def floor(scenario) -> WorldSpec:
    """A wall-less floor 0.5 m beyond the path, with the scenario's obstacles, start at the origin."""
    points = np.vstack([np.zeros(2), scenario["waypoints"]])
    low, high = points.min(axis=0) - 0.5, points.max(axis=0) + 0.5
    walls = tuple(Wall(tuple(map(tuple, polygon))) for polygon in scenario.params.get("walls", ()))
    return WorldSpec("floor", (*low, *high), walls=walls, starts=(Start(0.0, 0.0, 0.0),), floor_colour=(1.0, 1.0, 1.0))


def check(scenario, student):
    goal = np.array([*scenario["waypoints"][-1], scenario["heading"]], dtype=np.float64)
    world = floor(scenario)
    driver = RemoteController(student, "Driver", waypoints=scenario["waypoints"], heading=scenario["heading"])
    result = run(world, [RobotSetup(robot({}), driver, "driver")], float(scenario["time"]), seed=scenario.seed, observers=observers(scenario))
    driver.raise_error()
    log = result.robots[0]
    truth = log.truth_array()
    distance = np.hypot(*(truth[:, :2] - goal[:2]).T)
    error = np.abs(wrap_angle(truth[:, 2] - goal[2]))
    tol = scenario.tolerance
    inside = (distance <= tol["position"]) & (error <= tol["heading"])
    outside = np.flatnonzero(~inside)
    arrival = None if not inside[-1] else float(result.time[outside[-1] + 1] if outside.size else 0.0)
    deviation = float(path_distance(truth[:, :2], np.vstack([truth[0, :2], scenario["waypoints"]])).max())
    there = f"at {arrival:.1f} s" if arrival is not None else "not there"
    got = f"{distance[-1] * 1000:.0f} mm {error[-1]:.2f} rad {there}; path {deviation * 1000:.0f} mm; {log.collisions} collisions"
    expected = f"({goal[0]:.2f}, {goal[1]:.2f}, {goal[2]:.2f}) by {float(scenario['time']):g} s"
    tolerance = f"{tol['position']:g} m, {tol['heading']:g} rad, path {tol['path']:g} m, 0 collisions"
    moving = moved(truth, result.dt) > 0.005  # m in the last second: still on its way
    hint = ("collision" if log.collisions else "path" if deviation > tol["path"]
            else ("slow" if moving else "position") if distance[-1] > tol["position"]
            else "heading" if error[-1] > tol["heading"] else None)  # fmt: skip
    tracks = {"truth": (result.time, truth)}
    args = {"deviation": deviation, "distance": float(distance[-1]), "error": float(error[-1])}
    return Outcome(expected, got, hint is None, tolerance, hint, args, tracks=tracks, world=world)
