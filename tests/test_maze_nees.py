"""Every shipped estimator's covariance where the robot works: the main job (solve_maze in the
maze, realistic noise, until the goal or 300 s) on 120 seeds, the mean NEES at 10, 50 and 100 % of
each run inside the 95 % chi-square interval of 120 runs (2.58-3.45, `sim.analysis.nees.interval`).
Three sets of 40 (the docs' table gives each): a slide or a robot far out in the belief makes a
run's NEES tens or hundreds, and the mean of 40 such heavy-tailed draws strays further than the
40 runs' interval (2.29-3.81), made for chi-square draws, allows.

Each seed is a robot of its own, its wheels', track's and mouse resolution's errors drawn from
the belief (`Scenario(drawn=True)`): the interval describes runs whose errors are independent
draws of what the covariance states. The realistic preset's own errors are one robot, the same in
every seed; docs/odometry.md gives its figures beside these and says why its encoders end too
cautious there. The seeds run once for the whole module, on every core (`sim.experiments.engines`).
"""

from __future__ import annotations

import pytest

from sim.experiments.consistency import FRACTIONS, Scenario, consistency
from sim.experiments.engines import engine

SEEDS = [*range(100, 140), *range(200, 240), *range(300, 340)]
pytestmark = [pytest.mark.slow, pytest.mark.timeout(3600)]


@pytest.fixture(scope="module")
def maze():
    runner = engine("processes")
    try:
        return consistency(SEEDS, Scenario(drawn=True), runner=runner)
    finally:
        runner.close()


@pytest.mark.parametrize("fraction", FRACTIONS)
@pytest.mark.parametrize("name", ["encoders", "firmware", "mouse", "fused"])
def test_mean_nees_over_seeds_is_inside_the_chi_square_interval(maze, name, fraction):
    over = maze.over[name][FRACTIONS.index(fraction)]
    assert over.runs == len(SEEDS)
    assert over.verdict == "consistent", f"{name} at {fraction:.0%}: {over}"
