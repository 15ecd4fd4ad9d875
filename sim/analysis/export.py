"""A run's samples to files: Parquet (every sample: poses and readings, the run's primary data),
the TUM format that `evo` and the TUM RGB-D tools read, and CSV.

TUM (Sturm et al. 2012): one pose per line, `timestamp tx ty tz qx qy qz qw`, space separated,
lines starting with '#' are comments. A planar pose (x, y, theta) is (x, y, 0) with the unit
quaternion of a rotation by theta about z: (0, 0, sin(theta/2), cos(theta/2)).

Numbers are written by Arrow's CSV writer, each float in the fewest digits that read back bit for
bit: ten times numpy.savetxt's speed (a 2-hour run is 720,000 samples a trajectory).
"""

from __future__ import annotations

import csv
import io
import warnings
from contextlib import ExitStack
from pathlib import Path
from typing import BinaryIO, TextIO

import numpy as np

from bots.schema import file_stem
from bots.sensor_kinds import BY_FIELD
from bots.uncertainty import COVARIANCE_FIELDS
from sim.errors import UserError
from sim.out_files import replacing, temporary_beside

FILE_ROWS = 8192
"""Samples written at a time (a Parquet row group, a block of TUM and CSV lines): each block is a
table in memory that Arrow encodes (a c't-Bot's 30 Parquet columns: 2 MB), where the run's blocks of
65,536 samples added 40 MB to a long run's peak."""


def _checked(times: np.ndarray, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    times, poses = np.asarray(times, dtype=np.float64), np.asarray(poses, dtype=np.float64)
    if poses.ndim != 2 or poses.shape[1] != 3 or times.shape != (len(poses),):
        raise ValueError(f"expected T times and (T, 3) poses, got {times.shape} and {poses.shape}")
    return times, poses


TUM_HEADER = "# timestamp tx ty tz qx qy qz qw\n"


def _numbers(handle: BinaryIO, columns: list[np.ndarray], delimiter: str) -> None:
    """One line per row of `columns` (T values each), numbers separated by `delimiter`."""
    import pyarrow as pa
    import pyarrow.csv as pacsv

    table = pa.table([np.ascontiguousarray(column, dtype=np.float64) for column in columns], names=[str(k) for k in range(len(columns))])
    pacsv.write_csv(table, handle, pacsv.WriteOptions(include_header=False, delimiter=delimiter, quoting_style="none"))


def _tum_rows(handle: BinaryIO, times: np.ndarray, poses: np.ndarray) -> None:
    half = 0.5 * poses[:, 2]
    zeros = np.zeros(len(poses))
    _numbers(handle, [times, poses[:, 0], poses[:, 1], zeros, zeros, zeros, np.sin(half), np.cos(half)], " ")


def write_tum(path: str | Path, times: np.ndarray, poses: np.ndarray) -> None:
    """Write (T, 3) planar poses at `times` (s) as a TUM trajectory file."""
    times, poses = _checked(times, poses)
    with replacing(Path(path)) as handle:
        handle.write(TUM_HEADER.encode())
        _tum_rows(handle, times, poses)


def read_tum(path: str | Path | TextIO) -> tuple[np.ndarray, np.ndarray]:
    """(times (T,), poses (T, 3)) from a TUM file (or its text as a file); the heading is the
    rotation about z, unwrapped to stay continuous. Refuses poses that leave the plane."""
    text = path.read() if hasattr(path, "read") else Path(path).read_text(encoding="utf-8")
    rows = _tum_numbers(text)
    if rows.shape[1] != 8:
        raise UserError(f"{path}: a TUM line has 8 numbers (timestamp tx ty tz qx qy qz qw), found {rows.shape[1]}")
    if len(rows) and np.abs(rows[:, [3, 4, 5]]).max() > 1e-9:
        raise UserError(f"{path}: trajectory is not planar (nonzero tz, qx or qy)")
    heading = np.unwrap(2.0 * np.arctan2(rows[:, 6], rows[:, 7]))
    return rows[:, 0], np.column_stack((rows[:, 1], rows[:, 2], heading))


_COLUMNS = [f"c{k}" for k in range(8)]
_PLAIN = b"0123456789.eE+- \n"
"""The bytes of a TUM file's lines as ctsim writes them (`write_tum`): numbers and single spaces."""


def _tum_numbers(text: str) -> np.ndarray:
    """(T, 8) numbers of a TUM file's text. Lines of plain numbers each separated by one space
    under the leading comments (every file ctsim writes, `_PLAIN`) are read by Arrow's CSV reader
    in a sixth of np.loadtxt's time (the figures of a run read five such files); anything else
    (tabs, runs of spaces, comments further down, nan, a malformed number) by np.loadtxt, whose
    messages say what is wrong. Both read a number to the same float
    (tests/test_export.py holds them equal)."""
    body, start = text.encode(), 0
    while body.startswith(b"#", start):  # (the header; a comment further down is np.loadtxt's)
        start = body.find(b"\n", start) + 1 or len(body)
    body = body[start:]
    if body and not body.translate(None, _PLAIN):
        import pyarrow as pa
        import pyarrow.csv as pacsv

        try:
            table = pacsv.read_csv(
                io.BytesIO(body), pacsv.ReadOptions(column_names=_COLUMNS, use_threads=False), pacsv.ParseOptions(delimiter=" ", quote_char=False),
                pacsv.ConvertOptions(column_types=dict.fromkeys(_COLUMNS, pa.float64()), null_values=[], strings_can_be_null=False),
            )  # fmt: skip
        except pa.ArrowInvalid:  # (a malformed number, a line of other than 8: np.loadtxt says which)
            table = None
        if table is not None and table.num_rows:  # (blank lines alone: as np.loadtxt reads them)
            return np.column_stack([column.to_numpy() for column in table.columns])
    with warnings.catch_warnings():  # (a file of no poses: refused below, without numpy's warning line too)
        warnings.filterwarnings("ignore", "loadtxt: input contained no data", UserWarning)
        return np.loadtxt(io.StringIO(text), comments="#", ndmin=2)


def write_csv(path: str | Path, times: np.ndarray, poses: np.ndarray, extra: dict[str, np.ndarray] | None = None) -> None:
    """Write `t,x,y,theta` (s, m, rad) per row, then one column per `extra` entry (T values each)."""
    times, poses = _checked(times, poses)
    extra = {name: np.asarray(values, dtype=np.float64) for name, values in (extra or {}).items()}
    for name, values in extra.items():
        if values.shape != times.shape:
            raise ValueError(f"extra column {name!r} has shape {values.shape}, expected {times.shape}")
    with replacing(Path(path)) as handle:
        handle.write(_csv_header(["t", "x", "y", "theta", *extra]))
        _numbers(handle, [times, *poses.T, *extra.values()], ",")


def _csv_header(names: list[str]) -> bytes:
    line = io.StringIO()
    csv.writer(line).writerow(names)
    return line.getvalue().replace("\r\n", "\n").encode()


def read_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """(times, poses (T, 3), extra columns by name) from a file written by `write_csv`."""
    with open(path, newline="", encoding="utf-8") as handle:
        reader = csv.reader(handle)
        header = next(reader)
        if header[:4] != ["t", "x", "y", "theta"]:
            raise UserError(f"{path}: expected a header starting t,x,y,theta, got {','.join(header)}")
        values = np.array([[float(v) for v in row] for row in reader], dtype=np.float64).reshape(-1, len(header))
    return values[:, 0], values[:, 1:4], {name: values[:, 4 + k] for k, name in enumerate(header[4:])}


def write_run(result, directory: str | Path, prefix: bool = True, with_csv: bool = False, every: int = 1) -> dict[str, dict[str, Path]]:  # noqa: ANN001 (sim.run.samples.RunResult)
    """Every robot's truth and estimates as TUM files (and CSV with `with_csv`) named
    `<robot>_<label>` (just `<label>` without `prefix`), every `every`-th sample and the last,
    written block by block as the run is read through (`RunResult.blocks`), so memory does not
    grow with its length. A file that cannot be put in its place (a folder planted at its name)
    costs that file alone: the others are written, then its error raised. Robot name -> label ->
    TUM path."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    tracks = [(log.name, label, log) for log in result.robots for label in ("truth", *log.estimate_names)]
    stems = [directory / stem for stem in _stems([f"{file_stem(robot)}_{file_stem(label)}" if prefix else file_stem(label) for robot, label, _ in tracks])]
    per_group = max(1, MOST_OPEN // (2 if with_csv else 1))
    failed: list[Exception] = []
    for first in range(0, len(tracks), per_group):  # (a group's files open at once: at most MOST_OPEN handles)
        group = range(first, min(first + per_group, len(tracks)))
        with ExitStack() as stack:
            tum = [_each_alone(stack, Path(f"{stems[k]}.tum"), failed) for k in group]
            tables = [_each_alone(stack, Path(f"{stems[k]}.csv"), failed) for k in group] if with_csv else []
            for handle in tum:
                handle.write(TUM_HEADER.encode())
            for table in tables:
                table.write(_csv_header(["t", "x", "y", "theta"]))
            for rows in result.blocks(FILE_ROWS):
                picked = sampled(rows, len(result), every)
                within = slice(None) if isinstance(picked, slice) else picked - rows.start  # (the picked samples among the block's)
                times = result.time_array(rows)[within]
                for j, k in enumerate(group):
                    _, label, log = tracks[k]
                    chosen = log.poses_of(label, rows)[within]
                    _tum_rows(tum[j], times, chosen)
                    if with_csv:
                        _numbers(tables[j], [times, *chosen.T], ",")
    if failed:
        raise failed[0]
    written: dict[str, dict[str, Path]] = {}
    for (robot, label, _), stem in zip(tracks, stems):
        written.setdefault(robot, {})[label] = Path(f"{stem}.tum")
    return written


def _each_alone(stack: ExitStack, path: Path, failed: list[Exception]) -> BinaryIO:
    """`replacing(path)` entered into `stack`, its failure to take its place noted in `failed`
    rather than raised, so that the files entered before it are still put in theirs (an error of
    the writing itself still discards every one)."""
    writer = replacing(path)
    handle = writer.__enter__()

    def leave(*exc: object) -> bool:
        try:
            writer.__exit__(*exc)
        except (OSError, UserError) as err:  # (NotAFileOfItsOwn: a folder planted at its name)
            if exc[0] is not None:
                raise
            failed.append(err)
        return False

    stack.push(leave)
    return handle


MOST_OPEN = 64
"""Most trajectory files `write_run` holds open at once: a run of 120 robots writes 1,200, more
than a `ulimit -n` of 1,024 allows; groups of files are written one after another."""


def _stems(stems: list[str]) -> list[str]:
    """The file stems, made distinct where two names came out alike (`a b` and `a_b`): -2, -3, ..."""
    seen: dict[str, int] = {}
    distinct = []
    for stem in stems:
        seen[stem] = seen.get(stem, 0) + 1
        distinct.append(stem if seen[stem] == 1 else f"{stem}-{seen[stem]}")
    return distinct


def sampled(rows: slice, total: int, every: int) -> np.ndarray | slice:
    """The samples of block `rows` (of `total`) that are multiples of `every`, and the last sample
    of all: indices into the run's columns (the block itself when `every` is 1)."""
    if every <= 1:
        return rows
    picked = np.arange(-(-rows.start // every) * every, rows.stop, every)
    if rows.stop == total and (total - 1) % every:
        picked = np.append(picked, total - 1)
    return picked


def write_parquet(result, path: str | Path) -> Path:  # noqa: ANN001 (sim.run.samples.RunResult)
    """Every sample of a run as one Parquet table, a row per sample, written block by block:
    `time` (s); per robot `<robot>.<label>.x|y|theta` (m, rad) of the truth and each estimate,
    `<robot>.<label>.cov_xx|cov_xy|cov_xt|cov_yy|cov_yt|cov_tt` (m², m·rad, rad²) of each
    estimate that has a covariance; and its readings `<robot>.<field>.<channel>` in the devices' units, in the
    sensor registry's order (`Readings`: raw IR, IR distance m, line, border, light, encoder ticks
    and mouse counts of the step; a general chassis's per-wheel readings are in the recording only)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    path = Path(path)
    with temporary_beside(path) as temporary:  # (never through a link planted in the folder)
        writer = None
        try:
            for rows in result.blocks(FILE_ROWS) if len(result) else [slice(0, 0)]:  # (lazily: each block leaves memory as the next is read)
                table = pa.table({name: np.ascontiguousarray(column) for name, column in _columns(result, rows).items()})
                if writer is None:
                    writer = pq.ParquetWriter(temporary, table.schema)
                writer.write_table(table)
        finally:
            if writer is not None:
                writer.close()
    return path


def _columns(result, rows: slice) -> dict[str, np.ndarray]:  # noqa: ANN001 (sim.run.RunResult)
    """The Parquet columns of the samples `rows` (`write_parquet`)."""
    columns = {"time": result.time_array(rows)}
    for log in result.robots:
        for label, poses in {"truth": log.truth_array(rows), **log.estimate_arrays(rows)}.items():
            for k, axis in enumerate(("x", "y", "theta")):
                columns[f"{log.name}.{label}.{axis}"] = poses[:, k]
        for label, entries in log.covariance_arrays(rows).items():
            for k, entry in enumerate(COVARIANCE_FIELDS):
                columns[f"{log.name}.{label}.{entry}"] = entries[:, k]
        if log.spec.chassis is None:
            for name, values in log.readings(rows).items():
                for channel, column in zip(_channels(log.spec, name), values.T):
                    columns[f"{log.name}.{name}.{channel}"] = column
    return columns


def _channels(spec, name: str) -> tuple[str, ...]:  # noqa: ANN001 (bots.spec.RobotSpec)
    """Names of the channels of readings field `name` of a robot on a differential drive (none:
    the robot lacks that sensor)."""
    return BY_FIELD[name].channels_of(spec)


def read_parquet(path: str | Path) -> dict[str, np.ndarray]:
    """Column name -> values of a table written by `write_parquet`."""
    import pyarrow.parquet as pq

    table = pq.read_table(path)
    return {name: table.column(name).to_numpy() for name in table.column_names}


def export_run(result, directory: str | Path) -> list[Path]:  # noqa: ANN001 (sim.run.samples.RunResult)
    """One TUM file per robot and trajectory (`<robot>_truth.tum`, `<robot>_<estimator>.tum`), so
    that e.g. `evo_ape tum ctbot_truth.tum ctbot_encoders.tum` compares them; returns the paths."""
    return [path for labels in write_run(result, directory).values() for path in labels.values()]
