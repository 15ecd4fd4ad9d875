"""Whether the estimators' covariances tell the truth where the robot works: NEES over seeds.

A consistent estimator's mean NEES over N independent runs, each taken at the same point of its
run, lies in the chi-square interval of N runs (`sim.analysis.nees.interval`; 2.29-3.81 for 40).
`consistency` runs a scenario once per seed (by default the main job: solve_maze in the maze with
realistic noise, until the goal or 300 s), takes every estimate's NEES at fractions of each run
(10, 50 and 100 %) and gives the mean over the seeds with its interval and verdict:

    from sim.experiments.consistency import consistency
    print(consistency(range(100, 140)))        # a table: estimate x 10 / 50 / 100 %

Each run's readings can be kept (`keep=`, one `.npz` a seed): `replay` then scores changed
estimators on the same runs without simulating them again. That holds because the controller
drives by its own odometry, never by the estimates, so the runs would be the same.
"""

from __future__ import annotations

import math
import zlib
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bots.sensor_kinds import FRAMED
from bots.spec import BeliefSpec
from sim.analysis.nees import OverRuns, interval, nees, over_runs
from sim.experiments.api import Bot, robot, simulate
from sim.experiments.engines import Lost, Serial

FRACTIONS = (0.1, 0.5, 1.0)
"""Where in each run the NEES is taken: early, half-way, at the end."""
DRAW_KEY = zlib.crc32(b"systematic errors drawn")
"""The spawn key of the generator `drawn_errors` draws from (apart from every sensor's)."""


@dataclass(frozen=True)
class Scenario:
    """What every seed runs: a world, a controller, a noise preset, at most `duration` s, ended
    early at the goal where `until_goal`."""

    world: str = "maze"
    controller: str = "solve_maze"
    noise: str = "realistic"
    duration: float = 300.0
    until_goal: bool = True
    drawn: bool = False
    """Each seed a robot of its own: its wheels', track's and mouse resolution's errors drawn from
    the robot's belief (its stated tolerances), in place of the preset's, which are the same in
    every seed (one robot: for the part of the error they cause, 40 seeds are one draw)."""


MAZE = Scenario()
"""The main job: solve_maze in the maze, realistic noise, until the goal or 300 s."""


@dataclass
class Track:
    """One seed's run of the first robot: the sample times (T,), the true poses (T, 3), the
    encoder and mouse tallies each sample read (T, 4: left, right ticks, forward, lateral counts),
    and every estimate's poses (T, 3) and covariance entries (T, 6) as the run logged them."""

    seed: int
    time: np.ndarray
    truth: np.ndarray
    tallies: np.ndarray
    estimates: dict[str, np.ndarray]
    covariances: dict[str, np.ndarray]

    def save(self, path: Path) -> None:
        """The track as one `.npz` (`Track.load` reads it back)."""
        arrays = {f"estimate.{name}": poses for name, poses in self.estimates.items()}
        arrays |= {f"covariance.{name}": entries for name, entries in self.covariances.items()}
        np.savez_compressed(path, seed=self.seed, time=self.time, truth=self.truth, tallies=self.tallies, **arrays)

    @classmethod
    def load(cls, path: Path) -> Track:
        """A track `save` wrote."""
        with np.load(path) as data:

            def named(prefix: str) -> dict[str, np.ndarray]:
                return {key.removeprefix(prefix): data[key] for key in data.files if key.startswith(prefix)}

            return cls(int(data["seed"]), data["time"], data["truth"], data["tallies"], named("estimate."), named("covariance."))


def drawn_errors(belief: BeliefSpec, seed: int) -> dict[str, Any]:
    """Systematic errors of a robot built to these tolerances (robot changes by dotted name), drawn
    from a generator spawned from the run's seed: each wheel's diameter, the track and the mouse's
    resolution off by a normal draw of its believed standard deviation."""
    rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(DRAW_KEY,)))
    wheels = rng.normal(0.0, belief.wheel_diameter_std, 2)
    return {"encoders.diameter_error": (float(wheels[0]), float(wheels[1])), "encoders.track_error": float(rng.normal(0.0, belief.track_std)),
            "mouse.scale_error": float(rng.normal(0.0, belief.mouse_scale_std))}  # fmt: skip


def drive(seed: int, scenario: Scenario = MAZE) -> Track:
    """Run the scenario with this seed; its first robot's track."""
    changes = drawn_errors(robot("ctbot", noise=scenario.noise).belief, seed) if scenario.drawn else {}
    result = simulate(scenario.world, Bot(scenario.controller, changes=changes), noise=scenario.noise, duration=scenario.duration, seed=seed,
                      until_goal=scenario.until_goal)  # fmt: skip
    if result.error:
        raise RuntimeError(f"seed {seed}: {result.error}")
    log = result.raw.robots[0]
    readings = log.readings(slice(0, len(result.time)))
    tallies = np.concatenate([readings[kind.field] for kind in FRAMED if kind.frame == "tallies"], axis=1).astype(np.int64)  # (the registry's order)
    copied = {name: np.array(poses) for name, poses in log.estimate_arrays().items()}
    return Track(seed, np.array(result.time), np.array(log.truth_array()), tallies, copied,
                 {name: np.array(entries) for name, entries in log.covariance_arrays().items()})  # fmt: skip


def replay(track: Track, scenario: Scenario = MAZE) -> Track:
    """The track with its default estimates made anew from its tallies by the estimators as they
    are now (`bots.odometry.batch.DefaultOdometry`, as a run steps them)."""
    from bots.odometry.batch import COVARIANCES, DefaultOdometry
    from bots.odometry.layout import ESTIMATES

    odometry = DefaultOdometry([robot("ctbot", noise=scenario.noise)], track.truth[:1], [0])
    names = odometry.names[0]
    out, cov_out = np.zeros((len(track.time), 1, 1 + ESTIMATES, 3)), np.zeros((len(track.time), 1, ESTIMATES, COVARIANCES))
    tallies = np.ascontiguousarray(track.tallies, dtype=np.int64)
    for n, time in enumerate(track.time.tolist()):
        odometry.update_into(tallies[n : n + 1], time, track.truth[n : n + 1], out[n], cov_out[n])
    estimates = {name: out[:, 0, 1 + k] for k, name in enumerate(names)}
    return Track(track.seed, track.time, track.truth, track.tallies, estimates, {name: cov_out[:, 0, k] for k, name in enumerate(names)})


def sample_rows(length: int, fractions: Iterable[float] = FRACTIONS) -> list[int]:
    """The sample at each fraction of a run of `length` samples (1.0: the last)."""
    return [min(length - 1, max(0, math.ceil(f * (length - 1)))) for f in fractions]


def nees_at(track: Track, fractions: Iterable[float] = FRACTIONS) -> dict[str, np.ndarray]:
    """Each estimate's NEES (with a covariance) at these fractions of the run."""
    rows = sample_rows(len(track.time), fractions)
    return {name: nees(track.truth[rows], track.estimates[name][rows], entries[rows]) for name, entries in track.covariances.items()}


@dataclass(frozen=True)
class _Job:
    seed: int
    scenario: Scenario
    fractions: tuple[float, ...]
    keep: str | None


def _score(job: _Job) -> dict[str, np.ndarray]:
    """A worker's part: run one seed, keep its track where asked, give its NEES at the fractions."""
    track = drive(job.seed, job.scenario)
    if job.keep is not None:
        track.save(Path(job.keep) / f"seed{job.seed}.npz")
    return nees_at(track, job.fractions)


@dataclass
class Consistency:
    """Every estimate's mean NEES over the seeds at each fraction of the runs (`OverRuns`: the
    mean, its 95 % interval, the verdict) and each seed's values (seeds x fractions)."""

    seeds: list[int]
    fractions: tuple[float, ...]
    per_seed: dict[str, np.ndarray]
    over: dict[str, list[OverRuns]] = field(init=False)

    def __post_init__(self) -> None:
        self.over = {name: [over_runs(values[:, k]) for k in range(len(self.fractions))] for name, values in self.per_seed.items()}

    def consistent(self, name: str) -> bool:
        """Whether estimate `name` is inside its interval at every fraction."""
        return all(o.verdict == "consistent" for o in self.over[name])

    def __str__(self) -> str:
        first = next(iter(self.over.values()))[0] if self.over else None
        heads = " | ".join(f"{f:.0%}" for f in self.fractions)
        lines = [f"| estimate | {heads} |", "|---" * (1 + len(self.fractions)) + "|"]
        for name, overs in self.over.items():
            lines.append(f"| {name} | " + " | ".join(f"{o.mean:.3g}" + ("" if o.verdict == "consistent" else " *") for o in overs) + " |")
        if first is not None:
            lines.append(f"\nmean NEES over {first.runs} seeds; 95 % interval {first.low:.2f}-{first.high:.2f}; * outside it")
        return "\n".join(lines)

    def tails(self) -> str:
        """Each estimate's runs at each fraction against one run's chi-square (95 % of its draws
        within 0.22-9.35, `interval(1)`): the median NEES and, in brackets, the shares of runs
        below and above (2.5 % each for a consistent estimator). A mean over seeds outside its
        interval while the median is near chi-square's and the share above far over 2.5 % comes
        from a few runs, a heavy tail, whose mean over another set of seeds strays as far the other
        way; a median off chi-square's means the runs themselves are off."""
        low, high = interval(1)
        median = interval(1, level=0.0)[0]  # (an interval of 0 %: the median)
        heads = " | ".join(f"{f:.0%}" for f in self.fractions)
        lines = [f"| estimate | {heads} |", "|---" * (1 + len(self.fractions)) + "|"]
        for name, values in self.per_seed.items():
            cells = []
            for column in values.T:
                runs = column[np.isfinite(column)]
                cells.append(f"{np.median(runs):.2f} ({np.mean(runs < low):.1%} / {np.mean(runs > high):.1%})" if len(runs) else "-")
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
        lines.append(f"\nmedian NEES of one run (chi-square: {median:.2f}); in brackets the shares of runs below {low:.2f} and above {high:.2f} "
                     "(chi-square: 2.5 % each)")  # fmt: skip
        return "\n".join(lines)


def consistency(seeds: Iterable[int], scenario: Scenario = MAZE, fractions: Iterable[float] = FRACTIONS,
                runner: object | None = None, keep: str | Path | None = None) -> Consistency:  # fmt: skip
    """Run the scenario once per seed on `runner` (a `sim.experiments.engines` engine; default
    `Serial`) and take every estimate's NEES at `fractions` of each run; `keep`: a folder to save
    each run's track into (`Track.load`, `replay`)."""
    seeds, fractions = [int(s) for s in seeds], tuple(float(f) for f in fractions)
    if keep is not None:
        Path(keep).mkdir(parents=True, exist_ok=True)
    jobs = [_Job(s, scenario, fractions, None if keep is None else str(keep)) for s in seeds]
    by_seed: dict[int, dict[str, np.ndarray]] = {}
    for job, outcome in (runner or Serial()).imap(_score, jobs):
        if isinstance(outcome, Lost):
            raise RuntimeError(f"seed {job.seed}: {outcome.message}")
        by_seed[job.seed] = outcome
    names = list(by_seed[seeds[0]])
    return Consistency(seeds, fractions, {name: np.array([by_seed[s][name] for s in seeds]) for name in names})
