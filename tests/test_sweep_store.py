"""The sweep's result table on disk (`sim.experiments.store`): every finished run is kept exactly
once, through appends, compaction and a kill between compaction's rename and its clean-up."""

from __future__ import annotations

import shutil
from pathlib import Path

import pandas as pd
from hypothesis import given
from hypothesis import strategies as st

from sim.experiments import store


def _row(run: int, value: float = 0.0) -> dict:
    return {"run": run, "run_id": f"r{run:04d}", "ate_m": value}


def _rows_on_disk(out: Path) -> int:
    """Rows in every Parquet file of the folder, read directly: what `load` would have to drop."""
    return sum(len(pd.read_parquet(p)) for p in out.rglob("*.parquet"))


def test_each_append_writes_its_row_once(tmp_path):
    for run in (3, 1, 2):
        store.append(tmp_path, _row(run))
    assert _rows_on_disk(tmp_path) == 3
    frame = store.load(tmp_path)
    assert frame["run"].tolist() == [1, 2, 3]  # plan order, whatever the finishing order
    assert store.done(tmp_path) == {"r0001", "r0002", "r0003"}


def test_compact_folds_the_parts_into_one_table(tmp_path):
    for run in range(5):
        store.append(tmp_path, _row(run, value=run / 10))
    table = store.compact(tmp_path)
    assert not list((tmp_path / store.PARTS).glob("*.parquet"))
    assert _rows_on_disk(tmp_path) == 5 == len(table)
    pd.testing.assert_frame_equal(store.load(tmp_path), table)


def test_a_kill_between_rename_and_clean_up_doubles_nothing(tmp_path):
    """compact renamed results.parquet into place but was killed before removing the parts: every
    run is on disk twice, and `load` and `done` still see each once."""
    out, kept = tmp_path / "sweep", tmp_path / "kept"
    for run in range(4):
        store.append(out, _row(run))
    shutil.copytree(out / store.PARTS, kept)
    store.compact(out)
    shutil.copytree(kept, out / store.PARTS, dirs_exist_ok=True)
    assert _rows_on_disk(out) == 8
    assert store.load(out)["run_id"].tolist() == ["r0000", "r0001", "r0002", "r0003"]
    assert len(store.done(out)) == 4
    store.compact(out)
    assert _rows_on_disk(out) == 4


@given(st.lists(st.one_of(st.integers(0, 6), st.just("compact")), max_size=25))
def test_any_order_of_appends_and_compactions_keeps_every_run_once(tmp_path_factory, operations):
    """A model of the store: the set of runs appended so far, each once, in plan order."""
    out = tmp_path_factory.mktemp("sweep")
    appended: set[int] = set()
    for operation in operations:
        if operation == "compact":
            store.compact(out)
        elif operation not in appended:  # the sweep appends a run only when it is not done
            store.append(out, _row(operation))
            appended.add(operation)
    frame = store.load(out)
    assert (frame["run"].tolist() if len(frame) else []) == sorted(appended)
    assert _rows_on_disk(out) >= len(appended)
    if operations and operations[-1] == "compact":
        assert _rows_on_disk(out) == len(appended)
