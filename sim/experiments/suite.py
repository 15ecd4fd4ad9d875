"""The evaluation suite: fixed scenarios (world, controller, noise preset, duration) times seeds on
which `ctsim evaluate` scores estimators, so that two people's scores compare.

A scenario's hash covers everything that makes its runs what they are and that a ctsim version
might change under the same name: its settings, the world file's bytes and the robot's
description with its noise preset. A change to a scenario or to the seeds is a new
SUITE_VERSION, and results files of different versions or hashes are never merged
(`sim.experiments.evaluation`).

    from sim.experiments.suite import VARIANTS
    VARIANTS["short"].jobs(["my_filter.py:Filter"])     # the runs, each with its settings
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from sim.errors import UserError
from sim.experiments.plan import DEFAULTS, Job, run_id

SUITE_VERSION = "1"
"""The suite's version: raised whenever a scenario, a variant's seeds or what a hash covers changes."""


class SuiteError(UserError):
    """An unknown suite variant."""


@dataclass(frozen=True)
class Scenario:
    """One way to drive: a world of ctsim's `worlds/` folder (a `.toml` or a parcours `.xml` in
    c't-Sim's format), a registered controller with its parameters, a noise preset and how long
    (`until_goal`: or until the robot reaches the goal)."""

    name: str
    world: str
    controller: str
    noise: str
    duration: float
    params: tuple[tuple[str, Any], ...] = ()
    until_goal: bool = False

    def world_path(self) -> Path:
        from sim.world.files import worlds_dir

        return worlds_dir() / self.world

    def settings(self, seed: int) -> dict[str, Any]:
        """The run's settings as a sweep's (`sim.experiments.plan.DEFAULTS`), with `scenario`."""
        return {**DEFAULTS, "scenario": self.name, "world": str(self.world_path()), "controller": self.controller, "noise": self.noise,
                "seed": seed, "duration": self.duration, "until_goal": self.until_goal, **{f"params.{k}": v for k, v in self.params}}  # fmt: skip

    def digest(self) -> str:
        """sha256 of the scenario's settings, its world file's bytes and the robot it drives (the
        c't-Bot with its noise preset applied): the same hash means the same runs for a seed."""
        from sim.experiments.api import robot

        described = {"scenario": asdict(self), "robot": repr(robot(DEFAULTS["robot"], noise=self.noise)), "dt": DEFAULTS["dt"],
                     "world_sha256": hashlib.sha256(self.world_path().read_bytes()).hexdigest()}  # fmt: skip
        return hashlib.sha256(json.dumps(described, sort_keys=True, default=str).encode()).hexdigest()


@dataclass(frozen=True)
class Variant:
    """A named set of scenarios, each run with every seed."""

    name: str
    scenarios: tuple[Scenario, ...]
    seeds: tuple[int, ...]
    about: str

    def hashes(self) -> dict[str, str]:
        """Scenario name -> its `Scenario.digest`."""
        return {s.name: s.digest() for s in self.scenarios}

    def jobs(self, estimators: list[str] | tuple[str, ...] = (), identities: list[str] | tuple[str, ...] = (), step_timeout: float | None = None,
             isolate: bool = False) -> list[Job]:  # fmt: skip
        """Every run, scenario by scenario and seed by seed, each scoring `estimators` (sources as
        `bots.odometry.user.load` takes them) beside the shipped ones, each call of user code under
        `step_timeout` (`Job.step_timeout`), their files isolated where `isolate` (`Job.isolate`). A run's id covers its settings and the estimators'
        `identities` (what they are: a file's hash), so that a changed estimator is run again where
        a finished run of the old one was kept."""
        planned = []
        for scenario in self.scenarios:
            for seed in self.seeds:
                values = scenario.settings(seed)
                rid = run_id({**values, "world": scenario.world, "estimators": list(identities or estimators)})
                planned.append(Job(len(planned), rid, values, estimators=tuple(estimators), step_timeout=step_timeout, isolate=isolate))
        return planned


MAZE = "maze.toml"
ROOMS = "rooms.xml"
SQUARE = "square.toml"
EMPTY = "empty.toml"
LINE = "line.toml"

FULL_SCENARIOS = (
    Scenario("maze_none", MAZE, "solve_maze", "none", 300.0, until_goal=True),
    Scenario("maze_realistic", MAZE, "solve_maze", "realistic", 300.0, until_goal=True),
    Scenario("maze_harsh", MAZE, "solve_maze", "harsh", 300.0, until_goal=True),
    Scenario("rooms_realistic", ROOMS, "solve_maze", "realistic", 300.0, until_goal=True),
    Scenario("rooms_left_harsh", ROOMS, "follow_wall", "harsh", 300.0, until_goal=True),
    Scenario("line_none", LINE, "follow_line", "none", 120.0),
    Scenario("line_realistic", LINE, "follow_line", "realistic", 120.0),
    Scenario("square_realistic", SQUARE, "square", "realistic", 120.0, (("side_m", 1.0), ("laps", 3))),
    Scenario("empty_wander_realistic", EMPTY, "wander", "realistic", 120.0),
)
SHORT_SCENARIOS = (
    Scenario("maze_realistic_30s", MAZE, "solve_maze", "realistic", 30.0),
    Scenario("maze_harsh_30s", MAZE, "solve_maze", "harsh", 30.0),
    Scenario("rooms_realistic_30s", ROOMS, "solve_maze", "realistic", 30.0),
    Scenario("line_none_30s", LINE, "follow_line", "none", 30.0),
    Scenario("square_realistic_30s", SQUARE, "square", "realistic", 30.0, (("side_m", 0.5),)),
    Scenario("empty_wander_realistic_30s", EMPTY, "wander", "realistic", 30.0),
)
TEST_SCENARIOS = (
    Scenario("maze_realistic_4s", MAZE, "solve_maze", "realistic", 4.0),
    Scenario("line_none_20s", LINE, "follow_line", "none", 20.0),
)

VARIANTS: dict[str, Variant] = {
    "full": Variant("full", FULL_SCENARIOS, tuple(range(10)), "9 scenarios of up to 300 s, 10 seeds each: the suite to report"),
    "short": Variant("short", SHORT_SCENARIOS, (0, 1, 2), "6 scenarios of 30 s, 3 seeds each: about a minute on two cores, to try an estimator"),
    "test": Variant("test", TEST_SCENARIOS, (0, 1), "2 scenarios of a few seconds, 2 seeds each: for ctsim's own tests"),
}
"""The suite's variants by name (`ctsim evaluate --suite NAME`)."""


def variant(name: str) -> Variant:
    """The variant of that name; SuiteError names the known ones."""
    if name not in VARIANTS:
        raise SuiteError(f"unknown suite {name!r} (known: {', '.join(VARIANTS)})")
    return VARIANTS[name]
