"""Trajectories to files: the TUM format that `evo` and the TUM RGB-D tools read, and CSV.

TUM (Sturm et al. 2012): one pose per line, `timestamp tx ty tz qx qy qz qw`, space separated,
lines starting with '#' are comments. A planar pose (x, y, theta) is (x, y, 0) with the unit
quaternion of a rotation by theta about z: (0, 0, sin(theta/2), cos(theta/2)).
"""

from __future__ import annotations

import csv
from contextlib import ExitStack
from pathlib import Path
from typing import TextIO

import numpy as np

_FLOAT = "%.17g"  # enough digits that every float64 reads back bit for bit


def _checked(times: np.ndarray, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    times, poses = np.asarray(times, dtype=np.float64), np.asarray(poses, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] != 3 or times.shape != (len(poses),):
        raise ValueError(f"expected T times and (T, 3) poses, got {times.shape} and {poses.shape}")
    return times, poses


TUM_HEADER = "# timestamp tx ty tz qx qy qz qw\n"


def _tum_rows(handle: TextIO, times: np.ndarray, poses: np.ndarray) -> None:
    half = 0.5 * poses[:, 2]
    zeros = np.zeros(len(poses))
    np.savetxt(handle, np.column_stack((times, poses[:, 0], poses[:, 1], zeros, zeros, zeros, np.sin(half), np.cos(half))), fmt=_FLOAT)


def write_tum(path: str | Path, times: np.ndarray, poses: np.ndarray) -> None:
    """Write (T, 3) planar poses at `times` (s) as a TUM trajectory file."""
    times, poses = _checked(times, poses)
    with open(path, "w", encoding="utf-8") as handle:
        handle.write(TUM_HEADER)
        _tum_rows(handle, times, poses)


def read_tum(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """(times (T,), poses (T, 3)) from a TUM file; the heading is the rotation about z, unwrapped
    to stay continuous. Refuses poses that leave the plane."""
    rows = np.loadtxt(path, comments="#", ndmin=2)
    if rows.shape[1] != 8:
        raise ValueError(f"{path}: a TUM line has 8 numbers (timestamp tx ty tz qx qy qz qw), found {rows.shape[1]}")
    if len(rows) and np.abs(rows[:, [3, 4, 5]]).max() > 1e-9:
        raise ValueError(f"{path}: trajectory is not planar (nonzero tz, qx or qy)")
    heading = np.unwrap(2.0 * np.arctan2(rows[:, 6], rows[:, 7]))
    return rows[:, 0], np.column_stack((rows[:, 1], rows[:, 2], heading))


def write_csv(path: str | Path, times: np.ndarray, poses: np.ndarray, extra: dict[str, np.ndarray] | None = None) -> None:
    """Write `t,x,y,theta` (s, m, rad) per row, then one column per `extra` entry (T values each)."""
    times, poses = _checked(times, poses)
    extra = {name: np.asarray(values, dtype=np.float64) for name, values in (extra or {}).items()}
    for name, values in extra.items():
        if values.shape != times.shape:
            raise ValueError(f"extra column {name!r} has shape {values.shape}, expected {times.shape}")
    with open(path, "w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["t", "x", "y", "theta", *extra])
        _csv_rows(writer, [times, *poses.T, *extra.values()])


def _csv_rows(writer, columns: list[np.ndarray]) -> None:  # noqa: ANN001 (a csv writer)
    writer.writerows(zip(*(map(repr, map(float, c)) for c in columns)))


def read_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(times, poses (T, 3), extra columns by name) from a file written by `write_csv`."""
    with open(path, newline="", encoding="utf-8") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        if header[:4] != ["t", "x", "y", "theta"]:
            raise ValueError(f"{path}: expected a header starting t,x,y,theta, got {','.join(header)}")
        values = np.array([[float(v) for v in row] for row in reader], dtype=np.float64).reshape(-1, len(header))
    return values[:, 0], values[:, 1:4], {name: values[:, 4 + k] for k, name in enumerate(header[4:])}


def write_run(result, directory: str | Path, prefix: bool = True, with_csv: bool = False) -> dict[str, dict[str, Path]]:  # noqa: ANN001 (sim.run.RunResult)
    """Every robot's truth and estimates as TUM files (and CSV with `with_csv`) named
    `<robot>_<label>` (just `<label>` without `prefix`), written block by block as the run is read
    through (`RunResult.blocks`), so memory does not grow with its length.
    Robot name -> label -> TUM path."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    tracks = [(log.name, label, poses) for log in result.robots for label, poses in {"truth": log.truth_array(), **log.estimate_arrays()}.items()]
    stems = [directory / (f"{robot}_{label}" if prefix else label) for robot, label, _ in tracks]
    with ExitStack() as stack:
        tum = [stack.enter_context(open(f"{stem}.tum", "w", encoding="utf-8")) for stem in stems]
        tables = [csv.writer(stack.enter_context(open(f"{stem}.csv", "w", newline="", encoding="utf-8"))) for stem in stems] if with_csv else []
        for handle in tum:
            handle.write(TUM_HEADER)
        for table in tables:
            table.writerow(["t", "x", "y", "theta"])
        for rows in result.blocks():
            times = result.time[rows]
            for k, (_, _, poses) in enumerate(tracks):
                _tum_rows(tum[k], times, poses[rows])
                if with_csv:
                    _csv_rows(tables[k], [times, *poses[rows].T])
    written: dict[str, dict[str, Path]] = {}
    for (robot, label, _), stem in zip(tracks, stems):
        written.setdefault(robot, {})[label] = Path(f"{stem}.tum")
    return written


def export_run(result, directory: str | Path) -> list[Path]:  # noqa: ANN001 (sim.run.RunResult)
    """One TUM file per robot and trajectory (`<robot>_truth.tum`, `<robot>_<estimator>.tum`), so
    that e.g. `evo_ape tum ctbot_truth.tum ctbot_encoders.tum` compares them; returns the paths."""
    return [path for labels in write_run(result, directory).values() for path in labels.values()]
