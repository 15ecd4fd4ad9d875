"""Kidnapping a robot in a run, and how soon the map-aided localiser finds it again.

`Kidnapper` is an observer (`simulate(..., observers=[...])`) that puts robot 0 elsewhere at a
time and notes, per sample after it, the localiser's position error and its `lost` flag;
`recovery` reads those rows: when it said lost, when it said found on the robot, and every time it
said found while off. `KeepDriving` is solve_maze started again wherever it ends (it may fail or
finish soon after a kidnapping), so that the robot keeps giving the localiser scans to find it by.

    python -m sim.experiments.kidnap five 0 5      # the five places of docs/odometry.md, seeds 0-5
    python -m sim.experiments.kidnap drawn 0 9     # ten poses drawn from the maze's free floor
    python -m sim.experiments.kidnap rooms 0 9     # worlds/rooms.xml, carried 3 m, seeds 0-9
    python -m sim.experiments.kidnap five 2 2 --after 300   # a longer window

prints one JSON line a kidnapping (AFTER s after it unless --after says, one core):
docs/odometry.md's tables.
"""

from __future__ import annotations

import json
import math
import sys
import time

import numpy as np

from bots.behaviours import make
from bots.behaviours.base import RUNNING, Behaviour
from bots.odometry.localiser import MonteCarloLocaliser
from bots.readings import Readings

KIDNAP_AT = 30.0
"""When the scripted kidnappings happen (s): solve_maze, seed 0, drives along a corridor then."""
FOUND_WITHIN = 0.1
"""A localiser is on the robot within this (m): FOUND_SPREAD, the widest spread its search may end with."""
PLACES = ((2.76, 0.36, math.pi / 2), (0.36, 2.76, 0.0), (1.80, 1.80, math.pi), (2.52, 2.28, -math.pi / 2), (0.84, 0.84, math.pi / 2))
"""Poses of the maze the robot is carried to (x, y m, heading rad): cell centres, far from the
start corridor."""
ROOMS_PLACE = (3.0, 1.8, math.pi)
"""Where `rooms` carries the robot in worlds/rooms.xml: 3 m across the parcours, facing west."""
AFTER = 120.0
"""How long (s) a kidnapping runs after the robot is carried: the localiser's RECOVERY_TIME or more."""
DRAWN = 77
"""The generator from which `drawn` takes its poses (`MapScan.free`)."""


class Kidnapper:
    """Puts robot 0 elsewhere at `when` (moved `by` (x, y m, heading rad) from where it is, or
    put `at` a pose), and notes, per sample after it, the time since, the localiser's position
    error and its `lost` flag (`rows`), and the longest wall-clock time between two samples
    (`stall`, s: a localiser's search stalls the window of `ctsim play` that long)."""

    def __init__(self, by: tuple[float, float, float] | None = None, at: tuple[float, float, float] | None = None, when: float = KIDNAP_AT):
        self.by, self.at, self.when = by, at, when
        self.rows: list[tuple[float, float, bool]] = []
        self.stall, self._clock = 0.0, math.nan

    def on_sample(self, world, logs) -> None:  # noqa: ANN001
        if world.time < self.when:
            return
        if not self.rows:
            pose = world.poses()[0]
            world.reset_robot(0, tuple(pose + self.by) if self.by is not None else self.at)
        now = time.perf_counter()
        self.stall, self._clock = max(self.stall, now - self._clock) if self.rows else 0.0, now
        localiser = next(e for e in logs[0].estimators if isinstance(e, MonteCarloLocaliser))
        truth = world.poses()[0]
        self.rows.append((world.time - self.when, math.hypot(*(localiser.pose[:2] - truth[:2])), localiser.lost))


class KeepDriving(Behaviour):
    """solve_maze, started again (its rooms' grid on where it then believes it is) whenever it
    ends: a robot put down elsewhere may fail a drive or say it is done, and a run that ends gives
    the localiser no more scans."""

    def start(self) -> None:
        self.child = self.run(make("solve_maze", {}))

    def act(self, t: float, readings: Readings) -> object:
        if self.child.status is not RUNNING:
            self.child = self.run(make("solve_maze", {}))
        return self.child.step(t, readings)


def recovery(rows: np.ndarray) -> dict[str, float]:
    """Of a `Kidnapper`'s rows: when the localiser first said lost (s after the kidnapping), when it
    first said found while on the robot (`found`, nan if never), how often it said found while
    FOUND_WITHIN or more off (`wrong`), the longest of those (s) and the most it was off then (m)."""
    t, error, lost = rows[:, 0], rows[:, 1], rows[:, 2].astype(bool)
    found, wrong = math.nan, []
    for start in np.flatnonzero(lost[:-1] & ~lost[1:]) + 1:
        end = start + int(np.argmax(lost[start:])) if lost[start:].any() else len(t)
        if error[start] >= FOUND_WITHIN:
            wrong.append((float(t[end - 1] - t[start]), float(error[start:end].max())))
        elif math.isnan(found):
            found = float(t[start])
    return {
        "lost": float(t[lost][0]) if lost.any() else math.nan,
        "found": found,
        "wrong": len(wrong),
        "wrong_s": max((s for s, _ in wrong), default=0.0),
        "wrong_m": max((m for _, m in wrong), default=0.0),
    }


def kidnapping(place: tuple[float, float, float], seed: int, after: float = AFTER, world: str = "maze") -> dict:
    """One kidnapping: KeepDriving in `world` with realistic noise and the localiser, carried to
    `place` at KIDNAP_AT, run `after` s more; `recovery` of it, the longest stall, the wall time."""
    from sim.experiments.api import Bot, simulate

    kidnapper = Kidnapper(at=place)
    start = time.perf_counter()
    simulate(world, Bot(KeepDriving()), noise="realistic", duration=KIDNAP_AT + after, seed=seed, estimators=["localiser"], observers=[kidnapper])
    return {"place": [round(v, 3) for v in place], "seed": seed, **recovery(np.array(kidnapper.rows)), "stall": kidnapper.stall, "wall": time.perf_counter() - start}


def drawn(count: int) -> list[tuple[float, float, float]]:
    """`count` poses drawn from the maze's free floor (generator DRAWN), any heading."""
    from sim.experiments.api import robot, world
    from sim.world.localising import MapScan

    return [tuple(map(float, p)) for p in MapScan(world("maze"), robot("ctbot")).free(np.random.default_rng(DRAWN), count)]


def main(argv: list[str]) -> None:
    """`five FIRST LAST`: PLACES x seeds FIRST-LAST; `drawn FIRST LAST`: the drawn poses
    FIRST-LAST, each with its index as seed; `rooms FIRST LAST`: worlds/rooms.xml, carried 3 m to
    ROOMS_PLACE, seeds FIRST-LAST; `--after S` runs S s after each kidnapping. A wrong argument is argparse's usage line and exit status 2."""
    import argparse

    from sim.world.files import worlds_dir

    parser = argparse.ArgumentParser(prog="python -m sim.experiments.kidnap", description="Kidnappings and how soon the localiser finds the robot again (one JSON line each).")
    parser.add_argument("which", choices=("five", "drawn", "rooms"))
    parser.add_argument("first", type=int)
    parser.add_argument("last", type=int)
    parser.add_argument("--after", type=float, default=AFTER, help=f"seconds run after each kidnapping (default {AFTER:g})")
    arguments = parser.parse_args(argv)
    which, first, last = arguments.which, arguments.first, arguments.last
    if not 0 <= first <= last:
        parser.error(f"need 0 <= FIRST <= LAST, got {first} and {last}")
    world = str(worlds_dir() / "rooms.xml") if which == "rooms" else "maze"
    seeds = range(first, last + 1)
    runs = {"five": [(p, s) for p in PLACES for s in seeds], "rooms": [(ROOMS_PLACE, s) for s in seeds]}.get(which) or [(p, i) for i, p in enumerate(drawn(last + 1)) if i >= first]
    for place, seed in runs:
        print(json.dumps({k: round(v, 3) if isinstance(v, float) else v for k, v in kidnapping(place, seed, after=arguments.after, world=world).items()}), flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
