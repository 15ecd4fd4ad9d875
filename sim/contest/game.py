"""One game of a contest, start to verdict, in whatever process runs it: a preliminary run (one
entry alone against the clock) or a race of two, recorded for rerun with each bot in its own
colour and named on the map.

`play` takes a `GameJob` (plain data) and returns plain data, so that a game runs the same in this
process, a local worker or a Dask worker, and the conductor alone writes the contest's database.
Side i starts from the world's i-th start slot (`WorldSpec.start_order`) and races to that slot's
goals. Every game runs with the contest's seed: a game between the same two entries in the same
world is the same game, bit for bit (`digest` is a hash of every pose and time of the run).
"""

from __future__ import annotations

import hashlib
import time
import traceback
from contextlib import ExitStack
from dataclasses import asdict, dataclass
from functools import lru_cache
from pathlib import Path
from typing import Any

from bots.ctbot import CTBOT
from sim.contest.entries import Entry, Seat, robot_spec
from sim.contest.judge import Guarded, Judge
from sim.contest.paths import PathField
from sim.contest.rules import level_name, wall_budget
from sim.run.ending import Ending, Terminated
from sim.run.loop import run
from sim.run.samples import RunResult
from sim.views import palette
from sim.world.files import load_world
from sim.world.spec import WorldSpec

STEP_TIMEOUT = 30.0
"""Seconds of wall-clock time one controller step may take before it fails its robot (a file's
endless loop; a firmware's and a sandbox's own limits, 10 s, speak first)."""


@dataclass(frozen=True)
class GameJob:
    """A game to play: its place in the contest (`level`, `number`), its entries (one in the
    preliminary round, else two, the better preliminary first), the world (a shipped name or a
    file), the time limit (s), seed, step (s) and where to write its recording (None: nowhere)."""

    level: int
    number: int
    entries: tuple[Entry, ...]
    world: str
    time_limit: float
    seed: int
    dt: float
    recording: str | None

    @property
    def title(self) -> str:
        names = " vs ".join(e.name for e in self.entries)
        return f"{level_name(self.level)} {self.number}: {names}"


@lru_cache(maxsize=8)
def _world(source: str) -> WorldSpec:
    return load_world(source)


@lru_cache(maxsize=16)
def path_field(source: str, slot: int | None, clearance: float) -> PathField:
    """The way-left field to the goals of `slot` in world `source`, built once per process."""
    world = _world(source)
    return PathField(world, world.goals_of(slot), clearance)


def play(job: GameJob) -> dict[str, Any]:
    """Play `job` and return its outcome as plain data: per side `arrival`, `fell`, `failed`,
    `distance_left`, `end_time`; the `verdict` (`winner` 0/1, None alone; `reason`, `text`, `time`);
    the run's `reason` (the judge's call where it ended the run) and `error`; `digest`; `wall_time`. A game that cannot be played (a world that
    does not load, no free address for a firmware) returns `crash` with the reason instead; a
    Ctrl-C inside the run is raised again."""
    started = time.perf_counter()
    try:
        outcome = _play(job)
    except KeyboardInterrupt:
        raise
    except Exception as err:  # not the entries' fault (theirs is judged): the conductor stops and says so
        return {"crash": f"{job.title}: {type(err).__name__}: {err}", "traceback": traceback.format_exc()}
    outcome["wall_time"] = time.perf_counter() - started
    return outcome


def _play(job: GameJob) -> dict[str, Any]:
    world = _world(job.world)
    starts = world.start_order()[: len(job.entries)]
    specs = [robot_spec(entry, CTBOT) for entry in job.entries]
    clearance = 0.5 * CTBOT.body_radius  # the centre never gets nearer a wall than the body's radius
    fields = [path_field(job.world, start.slot, clearance) for start in starts]
    colours = {entry.name: colour for entry, colour in zip(job.entries, palette.CONTESTANTS)}
    recorder = None
    if job.recording is not None:
        from sim.views.recording.recorder import Recorder

        facts = {"contest game": job.title, "time limit": f"{job.time_limit:g} s"}
        recorder = Recorder(job.recording, application_id="ctsim contest", facts=facts, colours=colours)
    with ExitStack() as stack:  # a firmware's process, a sandbox: gone when the game is
        seats = [stack.enter_context(Seat(entry, spec, start, job.dt, f"{job.level}.{job.number}")) for entry, spec, start in zip(job.entries, specs, starts)]
        setups = [seat.setup(recorder) for seat in seats]
        guards = [Guarded(setup.controller, spec, wall_budget(job.time_limit)) for setup, spec in zip(setups, specs)]
        for setup, guard in zip(setups, guards):
            setup.controller = guard
        judge = Judge(tuple(entry.name for entry in job.entries), guards, fields, job.time_limit)
        observers = [o for o in [judge, recorder, *(o for seat in seats for o in seat.observers)] if o is not None]  # the judge first: its verdict goes into the recording
        result = run(world, setups, job.time_limit, dt=job.dt, seed=job.seed, observers=tuple(observers), step_timeout=STEP_TIMEOUT, stop_when=judge.stop_when)
    if result.reason.signalled:  # not decided: the game is played again on resuming
        raise (Terminated if result.reason is Ending.TERMINATED else KeyboardInterrupt)(result.error)
    outcome: dict[str, Any] = {"sides": [asdict(side) for side in judge.race], "verdict": asdict(judge.verdict), "reason": result.verdict or result.reason,
                               "error": result.error, "digest": digest(result)}  # fmt: skip
    if job.recording is not None:
        outcome["recording"] = str(Path(job.recording))
    return outcome


def digest(result: RunResult) -> str:
    """A hash of every sample time and every robot's true pose: equal for bit-identical runs."""
    h = hashlib.sha256(result.time.tobytes())
    for log in result.robots:
        h.update(log.truth_array().tobytes())
    return h.hexdigest()
