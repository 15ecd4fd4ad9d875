"""rerun and Arrow, imported lazily and fed cheaply: whole columns built in one go, data Arrow
owns, and pandas kept out of pyarrow's first look."""

from __future__ import annotations

import os
import sys
from typing import Any

import numpy as np


def quiet_rerun() -> None:
    """Silence rerun's own log lines (unless RUST_LOG says otherwise), before rerun is imported:
    its Rust side writes them straight to the terminal, coloured with escape sequences and with
    what they quote (a folder's name) past ctsim's sanitiser. The recorder says in one line of
    its own what failed (a lost viewer, a file that stopped taking writes: `file_trouble`)."""
    os.environ.setdefault("RUST_LOG", "off")


def lazy_rerun():
    """rerun, imported lazily (0.5 s, 80 MB), its own log lines silenced (`quiet_rerun`)."""
    quiet_rerun()
    import rerun

    return rerun


class _NoPandas:
    """Import finder under which pandas cannot be found."""

    def find_spec(self, name: str, path: Any = None, target: Any = None) -> None:
        if name == "pandas":
            raise ModuleNotFoundError("not while pyarrow looks", name=name)


def keep_pandas_out_of_arrow() -> None:
    """pyarrow imports pandas (about 40 MB resident) on its first conversion of a Python list,
    only to ask whether the list is a pandas object, and rerun converts its strings so. A
    recording holds no pandas objects: where pandas is not loaded yet, pyarrow's first look is
    made while pandas cannot be found, and pyarrow remembers it as absent for the process.
    Whatever needs pandas itself later (`to_pandas`, `to_parquet`) still imports it, and pyarrow
    then uses it again; but pyarrow's quiet checks stay negative until then (nanosecond
    timestamps read back as Python objects refuse without pandas). So only the `ctsim run` and
    `ctsim bridge` commands call this: their process records and runs no code of a user's after."""
    if "pandas" in sys.modules:
        return
    import pyarrow

    finder = _NoPandas()
    sys.meta_path.insert(0, finder)
    try:
        pyarrow.array(["ctsim"])
    finally:
        sys.meta_path.remove(finder)


class ArrowOwned:
    """A time or component column whose Arrow data rerun gets as a copy that Arrow owns.
    rerun frees each chunk in its file-writing thread after writing it, and memory that numpy
    owns can only be freed holding the GIL: that thread would then wake at every GIL release of
    the run loop (a context switch every few steps, 55,000 in a 30-minute run against 7,000 with
    the copy), which made a recorded run a tenth slower."""

    def __init__(self, column: Any):
        self._column = column

    def __getattr__(self, name: str) -> Any:
        return getattr(self._column, name)

    def as_arrow_array(self) -> Any:
        import pyarrow as pa

        # (one array: still a copy) in malloc's memory, as numpy's was (1-hour runs peaked at
        # 274-286 MB so, 288 MB in Arrow's default pool, mimalloc)
        return pa.concat_arrays([self._column.as_arrow_array()], memory_pool=pa.system_memory_pool())


def strips(points: np.ndarray, offsets: np.ndarray) -> Any:
    """Line strips points[offsets[j]:offsets[j + 1]] as rerun's arrow array, built in one go
    (rerun converts a list of strips one by one, and counts an array's in a Python loop: 20 us a
    sample for the trails and rays)."""
    import pyarrow as pa

    rr = lazy_rerun()
    inner = rr.components.Position2DBatch(points).as_arrow_array()
    return pa.ListArray.from_arrays(offsets.astype(np.int32), inner, type=rr.components.LineStrip2DBatch._ARROW_DATATYPE)


def xyz(poses: np.ndarray) -> np.ndarray:
    return np.column_stack((poses[:, 0], poses[:, 1], np.zeros(len(poses))))


def turn(heading: np.ndarray) -> np.ndarray:
    """Quaternions (x, y, z, w) of rotations by `heading` about z."""
    half = 0.5 * np.asarray(heading)
    zero = np.zeros_like(half)
    return np.column_stack((zero, zero, np.sin(half), np.cos(half)))
