"""The contest's database: one SQLite file in the contest folder holding the settings, the entries,
the plan of every game and each game's result as it comes in, so that a contest killed at any
moment resumes where it stopped and a finished one can be queried (`sqlite3 contest.sqlite`).

Only the conductor writes it, one transaction per finished game (results, the winner moved on in
the tree, the preliminary ranking once the last preliminary run is in). The schema is `SCHEMA`
(README, "Contests").
"""

from __future__ import annotations

import json
import sqlite3
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sim.contest.entries import Entry
from sim.errors import UserError
from sim.out_files import own_file

FILE = "contest.sqlite"
SCHEMA = """
CREATE TABLE IF NOT EXISTS settings (     -- what the contest is: world, prelim_world, time_limit, seed, dt, ctsim
    key   TEXT PRIMARY KEY,
    value TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS entries (
    id     INTEGER PRIMARY KEY,           -- 1, 2, ... in the order given
    name   TEXT NOT NULL UNIQUE,
    kind   TEXT NOT NULL,                 -- controller | file | firmware | student
    source TEXT NOT NULL,                 -- registered name or absolute path
    params TEXT NOT NULL,                 -- JSON [[key, value], ...]
    seed   INTEGER                        -- rank in the preliminary round, 1 = fastest (NULL until it is over)
);
CREATE TABLE IF NOT EXISTS games (
    level     INTEGER NOT NULL,           -- -1 preliminary, 0 third place, 1 final, 2 semi-finals, 4 quarter-finals, ...
    number    INTEGER NOT NULL,           -- 1-based within the level, top to bottom of the tree
    entry1    INTEGER REFERENCES entries, -- the upper place in the tree; NULL until the game feeding it is over
    entry2    INTEGER REFERENCES entries, -- the lower place; NULL in the preliminary round (the better seed starts from slot 1)
    state     TEXT NOT NULL DEFAULT 'planned',  -- planned | done
    winner    INTEGER REFERENCES entries, -- NULL in the preliminary round
    reason    TEXT,                       -- goal | fall | failure | time limit
    verdict   TEXT,                       -- the judge's sentence
    time      REAL,                       -- s of simulated time when it was decided
    arrival1  REAL, arrival2  REAL,       -- s at its own goal, or NULL
    distance1 REAL, distance2 REAL,       -- path distance (m) left to its goal at the end
    out1      REAL, out2      REAL,       -- s it fell into a hole or its controller failed, or NULL
    error     TEXT,                       -- a failed controller's message
    recording TEXT,                       -- the game's rerun recording, relative to the contest folder
    digest    TEXT,                       -- SHA-256 of the run's times and poses (same game, same digest)
    wall_time REAL,                       -- s it took to compute
    finished  TEXT,                       -- when it was recorded (UTC)
    PRIMARY KEY (level, number)
);
"""
RESULT_COLUMNS = ("winner", "reason", "verdict", "time", "arrival1", "arrival2", "distance1", "distance2", "out1", "out2",
                  "error", "recording", "digest", "wall_time")  # fmt: skip


class StoreError(UserError):
    """A contest folder that holds another contest (message for the command line)."""


@dataclass(frozen=True)
class GameRow:
    """A game as the database holds it (see SCHEMA for the columns)."""

    level: int
    number: int
    entry1: int | None
    entry2: int | None
    state: str
    winner: int | None
    reason: str | None
    verdict: str | None
    time: float | None
    arrival1: float | None
    arrival2: float | None
    distance1: float | None
    distance2: float | None
    out1: float | None
    out2: float | None
    error: str | None
    recording: str | None
    digest: str | None
    wall_time: float | None
    finished: str | None

    @property
    def key(self) -> tuple[int, int]:
        return (self.level, self.number)


class Store:
    """The database of the contest in `folder` (created on first use)."""

    def __init__(self, folder: str | Path):
        self.path = Path(folder) / FILE
        self.path.parent.mkdir(parents=True, exist_ok=True)
        for name in (self.path, *(self.path.with_name(self.path.name + end) for end in ("-journal", "-wal", "-shm"))):
            own_file(name)  # (SQLite opens them by name: never through a link planted in the folder)
        self.db = sqlite3.connect(self.path, isolation_level=None)  # transactions are explicit: `transaction`
        self.db.execute("PRAGMA foreign_keys = ON")
        self.db.executescript(SCHEMA)

    def close(self) -> None:
        self.db.close()

    @contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """All or nothing: a kill in the middle leaves the database as it was before."""
        self.db.execute("BEGIN IMMEDIATE")
        try:
            yield self.db
        except BaseException:
            self.db.execute("ROLLBACK")
            raise
        self.db.execute("COMMIT")

    # --- the contest and its entries ---------------------------------------------------------

    def begin(self, settings: dict[str, str], entries: list[Entry]) -> None:
        """Write the settings and entries of a new contest, or check that they are those already
        here (a resumed contest); another contest in the same folder is refused."""
        stored = dict(self.db.execute("SELECT key, value FROM settings"))
        if not stored:
            with self.transaction() as db:
                db.executemany("INSERT INTO settings VALUES (?, ?)", sorted(settings.items()))
                db.executemany("INSERT INTO entries (id, name, kind, source, params) VALUES (?, ?, ?, ?, ?)",
                               [(i, e.name, e.kind, e.source, json.dumps(e.params)) for i, e in enumerate(entries, 1)])  # fmt: skip
            return
        differ = [k for k in settings if k != "ctsim" and stored.get(k) != settings[k]]
        if self.entries() != entries:
            differ.append("entries")
        if differ:
            raise StoreError(
                f"{self.path} holds another contest ({', '.join(differ)} differ): give another --out, or delete the folder to start again"
            )

    def settings(self) -> dict[str, str]:
        return dict(self.db.execute("SELECT key, value FROM settings"))

    def entries(self) -> list[Entry]:
        """The entries, by id (id i is `entries()[i - 1]`)."""
        rows = self.db.execute("SELECT name, kind, source, params FROM entries ORDER BY id")
        return [Entry(name, kind, source, tuple(tuple(p) for p in json.loads(params))) for name, kind, source, params in rows]

    def seeds(self) -> dict[int, int]:
        """Entry id -> its preliminary rank (1 = fastest), once the preliminary round is over."""
        return dict(self.db.execute("SELECT id, seed FROM entries WHERE seed IS NOT NULL"))

    def set_seeds(self, order: list[int]) -> None:
        """Rank the entries: `order` lists entry ids from fastest to slowest."""
        with self.transaction() as db:
            db.executemany("UPDATE entries SET seed = ? WHERE id = ?", [(rank, entry) for rank, entry in enumerate(order, 1)])

    # --- games -------------------------------------------------------------------------------

    def plan(self, games: list[tuple[int, int, int | None, int | None]]) -> None:
        """Add games (level, number, entry1, entry2) that are not planned yet."""
        with self.transaction() as db:
            db.executemany("INSERT OR IGNORE INTO games (level, number, entry1, entry2) VALUES (?, ?, ?, ?)", games)

    def games(self, where: str = "1", *args: Any) -> list[GameRow]:
        """Games matching an SQL condition, in the order they are played (preliminary first, then
        the first round ... the final, the game for third place before the final)."""
        rows = self.db.execute(f"SELECT * FROM games WHERE {where} ORDER BY level = -1 DESC, level DESC, number", args)
        return [GameRow(*row) for row in rows]

    def record(self, level: int, number: int, result: dict[str, Any], moves: list[tuple[int, int, int, int]]) -> None:
        """Store a finished game's result and move entries on: `moves` are (level, number, side
        1|2, entry id) of the games its winner (and a semi-final's loser) play next."""
        values = [result.get(column) for column in RESULT_COLUMNS]
        with self.transaction() as db:
            db.execute(
                f"UPDATE games SET state = 'done', {', '.join(f'{c} = ?' for c in RESULT_COLUMNS)}, finished = ? WHERE level = ? AND number = ?",
                (*values, time.strftime("%Y-%m-%d %H:%M:%S", time.gmtime()), level, number),
            )
            for to_level, to_number, side, entry in moves:
                db.execute(f"UPDATE games SET entry{side} = ? WHERE level = ? AND number = ?", (entry, to_level, to_number))
