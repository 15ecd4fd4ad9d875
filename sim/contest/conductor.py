"""The conductor: runs a contest from its database to the end, resuming where it stopped.

Preliminary round (each entry alone in the preliminary world), ranking, the knockout tree, then
round after round every game whose two entries are known, in parallel on an engine of
`sim.experiments.engines` (local processes by default, or Dask). Each finished game is written to
the database in one transaction with its winner moved on, so that a contest killed at any moment
and started again plays only the games that are not in the database yet, and ends the same.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import sim
from bots.noise import DEFAULT_NOISE
from sim.contest import rules
from sim.contest.entries import Entry
from sim.contest.game import GameJob, play
from sim.contest.rules import PRELIM, PrelimResult, level_name
from sim.contest.store import GameRow, Store
from sim.experiments.engines import Lost, Processes, Serial
from sim.experiments.progress import Progress
from sim.world.step import DEFAULT_DT

GAMES = "games"
"""Sub-folder of the contest folder for the games' recordings."""


class ContestError(RuntimeError):
    """A game that could not be played (not an entry's fault: those are judged); the contest stops,
    everything decided so far stays in the database."""


@dataclass(frozen=True)
class Settings:
    """What decides a contest: the world of the knockout games and of the preliminary round (shipped
    names or files), the time limit of a game (s), the seed of every game, the step (s) and the
    robots' noise preset (`bots.noise`; realistic, as every run by default)."""

    world: str
    prelim_world: str
    time_limit: float
    seed: int = 0
    dt: float = DEFAULT_DT
    noise: str = DEFAULT_NOISE

    def as_text(self) -> dict[str, str]:
        return {"world": self.world, "prelim_world": self.prelim_world, "time_limit": repr(self.time_limit), "seed": str(self.seed),
                "dt": repr(self.dt), "noise": self.noise, "ctsim": sim.__version__}  # fmt: skip


def conduct(settings: Settings, entries: list[Entry], out: str | Path, runner: Any = None, record: bool = True,
            say: Callable[[str], None] = print, progress: bool = True) -> Store:  # fmt: skip
    """Run (or resume) the contest in folder `out` to its end and return its database. `runner`:
    an engine (`sim.experiments.engines`; default local processes, one per core); `record`: write
    each game's rerun recording; `say`: where a line per finished game goes; `progress`: games
    done and left, rate and time left on stderr (`sim.experiments.progress`)."""
    out = Path(out)
    if len(entries) < 1:
        raise ValueError("a contest needs at least one entry")
    store = Store(out)
    store.begin(settings.as_text(), entries)
    entries = store.entries()
    ids = list(range(1, len(entries) + 1))
    runner = runner or (Serial() if len(entries) == 1 else Processes(min(len(entries), os.cpu_count() or 1)))
    store.plan([(PRELIM, i, i, None) for i in ids])
    games = len(ids) + len(rules.plan(len(ids)))  # (every game that will be played)
    told = Progress(games, len(store.games("state = 'done'")), "game", "contest", bar=False) if progress else None
    try:
        _conduct(store, settings, entries, out, runner, record, lambda line: _said(say, told, line))
    finally:
        if told is not None:
            told.close()
    return store


def _said(say: Callable[[str], None], progress: Progress | None, line: str) -> None:
    """A game's line, and one more game done."""
    say(line)
    if progress is not None:
        progress.update()


def _conduct(store: Store, settings: Settings, entries: list[Entry], out: Path, runner: Any, record: bool, say: Callable[[str], None]) -> None:
    """The preliminary round, the seeding from it, then the knockout rounds as their entries become known."""
    _play(store, store.games("level = -1 AND state = 'planned'"), settings, entries, out, runner, record, say)
    if not store.seeds():
        rows = store.games("level = -1")
        order = rules.prelim_order([PrelimResult(r.arrival1, math.inf if r.distance1 is None else r.distance1, r.time) for r in rows])
        store.set_seeds([rows[i].entry1 for i in order])
    seeds = store.seeds()
    by_rank = sorted(seeds, key=seeds.get)  # entry ids, fastest first
    store.plan([(g.level, g.number, *(None if r is None else by_rank[r] for r in g.sides)) for g in rules.plan(len(entries))])
    while ready := store.games("level >= 0 AND state = 'planned' AND entry1 IS NOT NULL AND entry2 IS NOT NULL"):
        _play(store, ready, settings, entries, out, runner, record, say)


def _play(store: Store, games: list[GameRow], settings: Settings, entries: list[Entry], out: Path, runner: Any, record: bool,
          say: Callable[[str], None]) -> None:  # fmt: skip
    """Play `games` on the engine and write each to the database as it finishes."""
    if not games:
        return
    seeds = store.seeds()
    jobs = []
    for game in games:
        sides = [game.entry1] if game.level == PRELIM else sorted((game.entry1, game.entry2), key=lambda e: seeds[e])
        recording = out / GAMES / _file_name(game, [entries[e - 1].name for e in sides]) if record else None
        world = settings.prelim_world if game.level == PRELIM else settings.world
        jobs.append((game, sides, GameJob(game.level, game.number, tuple(entries[e - 1] for e in sides), world, settings.time_limit,
                                          settings.seed, settings.dt, None if recording is None else str(recording), settings.noise)))  # fmt: skip
    if record:
        (out / GAMES).mkdir(parents=True, exist_ok=True)
    by_job = {id(job): (game, sides) for game, sides, job in jobs}
    for job, outcome in runner.imap(play, [job for _, _, job in jobs]):
        game, sides = by_job[id(job)]
        if isinstance(outcome, Lost):
            raise ContestError(f"{job.title}: {outcome.message}")
        if "crash" in outcome:
            raise ContestError(outcome["crash"])
        result = _result(game, sides, outcome, out)
        store.record(game.level, game.number, result, _moves(game, sides, outcome) if game.level != PRELIM else [])
        say(f"{job.title if game.level != PRELIM else f'preliminary {game.number}'}: {result['verdict']}")


def _file_name(game: GameRow, names: list[str]) -> str:
    level = "prelim" if game.level == PRELIM else level_name(game.level).replace(" ", "-")
    return f"{level}-{game.number}-{'-vs-'.join(names)}.rrd"


def _result(game: GameRow, sides: list[int], outcome: dict[str, Any], out: Path) -> dict[str, Any]:
    """The database's columns of a played game; sides (start order) mapped back to the tree's entry1/entry2."""
    race = outcome["sides"]
    recording = outcome.get("recording")
    result: dict[str, Any] = {"error": outcome["error"], "digest": outcome["digest"], "wall_time": outcome["wall_time"],
                              "recording": None if recording is None else str(Path(recording).relative_to(out))}  # fmt: skip
    positions = [game.entry1, game.entry2]
    for side, entry in zip(race, sides):
        k = positions.index(entry) + 1
        outs = [t for t in (side["fell"], side["failed"]) if t is not None]
        result.update({f"arrival{k}": side["arrival"], f"distance{k}": _finite(side["distance_left"]), f"out{k}": min(outs) if outs else None})
    verdict = outcome["verdict"]
    winner = None if verdict["winner"] is None else sides[verdict["winner"]]
    result.update(winner=winner, reason=verdict["reason"], verdict=verdict["text"], time=verdict["time"])
    return result


def _moves(game: GameRow, sides: list[int], outcome: dict[str, Any]) -> list[tuple[int, int, int, int]]:
    winner = sides[outcome["verdict"]["winner"]]
    loser = sides[1 - outcome["verdict"]["winner"]]
    moves = []
    for entry, where in ((winner, rules.winner_goes_to(game.level, game.number)), (loser, rules.loser_goes_to(game.level, game.number))):
        if where is not None:
            level, number, side = where
            moves.append((level, number, side + 1, entry))
    return moves


def _finite(value: float) -> float | None:
    """SQLite has no infinity in JSON-friendly form: a way that leads nowhere is NULL."""
    return value if math.isfinite(value) else None


def placings(store: Store) -> list[tuple[int, int]]:
    """(place, entry id) of a finished contest, best first (`rules.placings`)."""
    seeds = store.seeds()
    by_rank = sorted(seeds, key=seeds.get)
    rank_of = {entry: rank for rank, entry in enumerate(by_rank)}
    results = {}
    for game in store.games("level >= 0 AND state = 'done'"):
        loser = game.entry2 if game.winner == game.entry1 else game.entry1
        results[game.key] = (rank_of[game.winner], rank_of[loser])
    return [(place, by_rank[rank]) for place, rank in rules.placings(len(by_rank), results)]
