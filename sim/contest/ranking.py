"""The final ranking of a contest: one row per entry, best first, for the terminal and as CSV."""

from __future__ import annotations

import csv
from pathlib import Path

from sim.contest.conductor import placings
from sim.contest.rules import PRELIM, level_name
from sim.contest.store import Store
from sim.out_files import replacing

COLUMNS = ("place", "entry", "controller", "kind", "seed", "preliminary", "out in", "won")


def ranking(store: Store) -> list[dict[str, str | int]]:
    """Rows of COLUMNS: place (shared below 4th by those out in the same round), the entry's name,
    what it runs, its kind, its seed (preliminary rank), its preliminary run, the round it went out
    in ('-' for the winner) and how many knockout games it won."""
    entries = store.entries()
    seeds = store.seeds()
    prelim = {g.entry1: g for g in store.games("level = ?", PRELIM)}
    games = store.games("level >= 0 AND state = 'done'")
    rows = []
    for place, entry in placings(store):
        lost = [g for g in games if entry in (g.entry1, g.entry2) and g.winner != entry]
        out = level_name(lost[0].level) if lost else "-"  # the first game it lost (a semi-final's loser may lose again for third)
        run = prelim[entry]
        shown = f"{run.arrival1:.2f} s" if run.arrival1 is not None else f"{run.reason}, {_metres(run.distance1)} left"
        e = entries[entry - 1]
        rows.append({"place": place, "entry": e.name, "controller": e.label, "kind": e.kind, "seed": seeds[entry], "preliminary": shown,
                     "out in": out, "won": sum(g.winner == entry for g in games)})  # fmt: skip
    return rows


def _metres(value: float | None) -> str:
    return "no way" if value is None else f"{value:.2f} m"


def table(rows: list[dict[str, str | int]]) -> str:
    """The rows as a plain-text table with aligned columns."""
    cells = [list(COLUMNS)] + [[str(row[c]) for c in COLUMNS] for row in rows]
    widths = [max(len(r[k]) for r in cells) for k in range(len(COLUMNS))]
    return "\n".join("  ".join(cell.ljust(w) for cell, w in zip(r, widths)).rstrip() for r in cells)


def write_csv(rows: list[dict[str, str | int]], path: Path) -> Path:
    """The rows as CSV with a header line."""
    with replacing(path, text=True, newline="") as f:
        writer = csv.DictWriter(f, COLUMNS)
        writer.writeheader()
        writer.writerows(rows)
    return path
