"""Checker of exercise 7: the student's line follower on a short course (a straight with a gap,
then two bends) with a goal at its end; it passes when the robot reaches the goal in time."""

import math

import numpy as np

from sim.lab.artifacts import observers
from sim.lab.checking import Outcome
from sim.lab.runs import RemoteController, moved, path_distance, robot
from sim.run.loop import RobotSetup, run
from sim.world.spec import FloorLine, Goal, Start, WorldSpec

LEG = 0.35
"""m of line after the start and after each bend."""
GAP_AT = 0.15
"""m from the start where the gap begins."""
SPEED = 0.08
"""m/s a follower must average to reach the goal in time (the shipped one drives 0.15)."""


def draw(rng, index, ranges):
    bends = [float(rng.uniform(*ranges["bend"]) * rng.choice([-1.0, 1.0])) for _ in range(2)]
    return {"bends": bends, "gap": float(rng.uniform(*ranges["gap"]))}


def course(bends: list[float]) -> np.ndarray:
    """The line's corners (K, 2): from just behind the start, LEG after each bend."""
    points, heading = [np.array([-0.05, 0.0]), np.array([LEG, 0.0])], 0.0
    for bend in bends:
        heading += bend
        points.append(points[-1] + LEG * np.array([math.cos(heading), math.sin(heading)]))
    return np.array(points)


def world(bends: list[float], gap: float) -> WorldSpec:
    """The course with its gap, the goal a 12 cm square around its end, 0.3 m of floor around."""
    points = course(bends)
    end, size = points[-1], 0.06
    goal = Goal(((end[0] - size, end[1] - size), (end[0] + size, end[1] - size), (end[0] + size, end[1] + size), (end[0] - size, end[1] + size)))
    lines = (FloorLine(((-0.05, 0.0), (GAP_AT, 0.0))), FloorLine(((GAP_AT + gap, 0.0), *map(tuple, points[1:]))))
    low, high = points.min(axis=0) - 0.3, points.max(axis=0) + 0.3
    return WorldSpec("line course", (*low, *high), lines=lines, starts=(Start(0.0, 0.0, 0.0),), goals=(goal,), floor_colour=(0.94, 0.94, 0.94))


def check(scenario, student):
    bends, spec = scenario["bends"], world(scenario["bends"], scenario["gap"])
    points = course(bends)
    limit = round(2.0 + float(np.hypot(*np.diff(points, axis=0).T).sum()) / SPEED, 1)
    follower = RemoteController(student, "LineFollower")
    result = run(spec, [RobotSetup(robot({}), follower, "line follower")], limit, seed=scenario.seed, until_goal=True, observers=observers(scenario))
    follower.raise_error()
    log = result.robots[0]
    truth = log.truth_array()
    tracks = {"truth": (result.time, truth)}
    if log.goal_time is not None:
        return Outcome(f"goal by {limit:g} s", f"goal at {log.goal_time:.1f} s", True, tracks=tracks, world=spec)
    distance = float(path_distance(truth[-1:, :2], points)[0])
    moving = moved(truth, result.dt) > 0.005  # m in the last second: still on its way
    hint = "lost" if distance > 0.05 else "slow" if moving else "stopped"
    got = f"not there; {distance:.2f} m from the line" + ("" if moving else ", standing")
    return Outcome(f"goal by {limit:g} s", got, False, hint=hint, hint_args={"distance": distance}, tracks=tracks, world=spec)
