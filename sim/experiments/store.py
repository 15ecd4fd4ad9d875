"""A sweep's result table on disk: one Parquet row per run, safe against being killed at any moment.

Each finished run is written at once as its own small Parquet file in `DIR/parts/` (written
under a temporary name and renamed, so a file is either whole or absent). `compact` folds the
parts into `DIR/results.parquet` (again by rename) and then removes them; `load` reads both and
keeps one row per run id, so even a kill between the rename and the removal loses and doubles
nothing.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pandas as pd

from sim.out_files import subfolder, temporary_beside

RESULTS = "results.parquet"
PARTS = "parts"


def _write(frame: pd.DataFrame, path: Path) -> None:
    """Write a table under a temporary name, then rename it into place."""
    with temporary_beside(path) as temporary:
        frame.to_parquet(temporary, index=False)


def append(out: Path, row: dict[str, Any]) -> None:
    """Keep one finished run's row on disk."""
    _write(pd.DataFrame([row]), subfolder(out / PARTS) / f"{row['run_id']}.parquet")


def _tables(out: Path) -> list[pd.DataFrame]:
    paths = ([out / RESULTS] if (out / RESULTS).is_file() else []) + sorted((out / PARTS).glob("*.parquet"))
    return [pd.read_parquet(p) for p in paths]


def load(out: str | Path) -> pd.DataFrame:
    """Every run finished so far in a sweep folder, one row each, in plan order."""
    tables = [t for t in _tables(Path(out)) if len(t)]
    if not tables:
        return pd.DataFrame()
    frame = pd.concat(tables, ignore_index=True).drop_duplicates("run_id")
    return frame.sort_values("run", kind="stable").reset_index(drop=True)


def done(out: Path) -> set[str]:
    """Ids of the runs already finished in `out`."""
    return set().union(*(set(t["run_id"]) for t in _tables(out) if "run_id" in t))


def compact(out: Path) -> pd.DataFrame:
    """Fold the parts into results.parquet and remove them; the whole table."""
    parts = sorted((out / PARTS).glob("*.parquet"))
    frame = load(out)
    if parts or not (out / RESULTS).is_file():
        _write(frame, out / RESULTS)
    for path in parts:
        path.unlink()
    return frame
