"""Localiser benchmarks: the main job (solve_maze in the maze, realistic noise) with the Monte
Carlo localiser beside the default estimators, against the same run without it and the bare
world step, interleaved (the machine's speed drifts over seconds)."""

from __future__ import annotations

import time

from bench.world import maze_ctbot


def maze_run(steps: int, localiser: bool) -> float:
    """Steps per second of a whole run of `steps` steps (less where solve_maze reaches the goal)
    with or without `--estimator localiser`; both keep the default estimators in Python, as a
    run with an estimator of the user's does."""
    from sim.experiments.api import simulate

    start = time.perf_counter()
    result = simulate("maze", noise="realistic", duration=steps * 0.01, until_goal=True, estimators=["localiser"] if localiser else [_Still])
    return (len(result.raw) - 1) / (time.perf_counter() - start)


class _Still:
    """An estimator that does nothing: the run without the localiser steps its defaults in Python
    as the run with it does, so the two differ by the localiser alone."""

    name = "still"

    def reset(self, robot: object, pose: object) -> None:
        self.pose = pose

    def update(self, readings: object) -> None:
        pass


def figures(scale: float):
    """(name, unit, thunk) for the localiser benchmarks."""
    steps = int(30_000 * scale)  # 300 s simulated (full), 60 s (quick)
    measured: dict[str, float] = {}

    def once(kind: str) -> float:
        """The best of three of each kind, interleaved."""
        if not measured:
            for _ in range(3):
                for key, measure in (("world", lambda: maze_ctbot(steps, repeats=1)), ("plain", lambda: maze_run(steps, False)),
                                     ("localiser", lambda: maze_run(steps, True))):  # fmt: skip
                    measured[key] = max(measured.get(key, 0.0), measure())
        return measured[kind]

    yield "localiser_steps_per_s", "steps/s (the main job with --estimator localiser; 2,000 is 20x real time)", lambda: once("localiser")
    yield ("localiser_over_world_step", "(the localiser's cost per step over the bare world step's, same runs)",
           lambda: (1.0 / once("localiser") - 1.0 / once("plain")) * once("world"))
