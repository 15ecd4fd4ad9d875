"""A run folder read back defensively (`ctsim report`): the folder may have been edited by hand,
copied half-way, or be written by a run still going.

summary.json is read strictly: a regular file of bounded size, strict JSON (no NaN), nesting
bounded, and the keys the report uses checked against their declared Fields
(`bots.schema.Field`), each problem one line naming the file and the key. Trajectory files are
plain names inside the folder (no path leaves it), regular files of bounded size; a file that is
not a trajectory is named, never quoted (an error once showed /etc/passwd's first line).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, BinaryIO

from bots.schema import MAX_DEPTH, Field, FileError, Problem, open_regular, read_bytes
from sim.folder_lock import holder

SUMMARY = "summary.json"
RECORDING, SAMPLES, REPORT, TRAJECTORIES_FIGURE, ERRORS_FIGURE = "run.rrd", "run.parquet", "report.html", "trajectories.png", "errors.png"


@dataclass(frozen=True)
class RunFolder:
    """Every path of a run folder, named here once for every writer and reader (`ctsim run`,
    `bridge`, `play`, `report`, the web server, the lab, a sweep's kept runs): the recording, the
    samples table, summary.json, the report page and its figures, and the trajectories
    summary.json names (`trajectory_path`)."""

    root: Path

    @property
    def recording(self) -> Path:
        """The rerun recording (`sim.views.recording`)."""
        return self.root / RECORDING

    @property
    def samples(self) -> Path:
        """Every sample of the run as a table (`sim.analysis.export.write_parquet`)."""
        return self.root / SAMPLES

    @property
    def summary(self) -> Path:
        """summary.json (`sim.analysis.summary`), read back by `read_summary`."""
        return self.root / SUMMARY

    @property
    def report(self) -> Path:
        """The report page (`sim.web.report`)."""
        return self.root / REPORT

    @property
    def figures(self) -> tuple[Path, Path]:
        """The trajectories' and the errors' figures (`sim.views.figures`)."""
        return self.root / TRAJECTORIES_FIGURE, self.root / ERRORS_FIGURE

    @property
    def fixed(self) -> tuple[Path, ...]:
        """The files a run writes whatever its robots: recording, samples, summary, report, figures."""
        return self.recording, self.samples, self.summary, self.report, *self.figures
MOST_SUMMARY_BYTES = 64 * 2**20
"""Largest summary.json read (bytes): a 1,000-robot run writes about 2 MB."""
MOST_TRAJECTORY_BYTES = 2**30
"""Largest TUM file read (bytes): a 24-hour run at 100 Hz writes about 700 MB."""
MOST_ROBOTS = 100_000

_TEXT, _NUMBER, _COUNT = Field("text"), Field("number"), Field("integer", low=0)
_MAYBE_TEXT, _MAYBE_NUMBER = Field("text", optional=True), Field("number", optional=True)
ROBOT: dict[str, Any] = {"name": _TEXT, "controller": _TEXT, "distance": Field("number", "m", 0.0), "collisions": _COUNT,
                         "fell": Field("boolean"), "goal_time": _MAYBE_NUMBER, "params": Field("table"), "estimates": Field("table")}
"""The keys of each robot that the report reads (others are kept as they are)."""
TOP: dict[str, Any] = {"world": {"name": _TEXT, "source": _TEXT}, "seed": _COUNT, "dt": Field("number", "s", 0.0, above=True),
                       "time": Field("number", "s", 0.0), "reason": _TEXT, "error": _MAYBE_TEXT, "robots": Field("tables")}
"""The top-level keys the report reads."""
OPTIONAL = {"ctsim_version": _TEXT, "duration": _NUMBER, "noise": _TEXT}
ROBOT_OPTIONAL = {"robot": _TEXT, "status": _MAYBE_TEXT, "goal": _MAYBE_TEXT, "tum": Field("table")}


class RunFolderError(FileError):
    """A run folder (or its summary.json) that cannot be reported: `file: key: problem`."""


def read_summary(run_dir: str | Path) -> dict[str, Any]:
    """summary.json of a run folder, checked (see the module); RunFolderError naming file and key,
    or saying that the run is still going (or ended without writing its summary)."""
    path = RunFolder(Path(run_dir)).summary
    if not path.exists():
        raise RunFolderError(run_dir, None, f"not a run folder (no {SUMMARY})")
    data = read_bytes(path, RunFolderError, MOST_SUMMARY_BYTES)
    try:
        summary = json.loads(data.decode("utf-8"), parse_constant=_refuse)
    except UnicodeDecodeError:
        raise RunFolderError(path, None, "not UTF-8 text") from None
    except json.JSONDecodeError as err:
        raise RunFolderError(path, err.lineno, err.msg) from None
    except RecursionError:
        raise RunFolderError(path, None, f"nested deeper than {MAX_DEPTH} levels") from None
    except ValueError as err:  # (a constant: NaN, Infinity; or a number past Python's digit limit)
        raise RunFolderError(path, None, f"not strict JSON: {err}") from None
    _check(path, summary)
    if summary["reason"] == "running":
        owner = holder(Path(run_dir))
        if owner is not None:
            raise RunFolderError(run_dir, None, f"the run is still going ({owner}); report it once it has ended")
        raise RunFolderError(path, None, "the run ended without finishing its summary (it was killed, or its disk filled up): "
                                         "there is nothing to report")
    return summary


def written_by_ctsim(run_dir: str | Path) -> bool:
    """Whether the folder's summary.json is one a ctsim run wrote (a whole JSON object naming
    ctsim's version and how the run ended, a run cut short included): only then may a new run
    replace its files; someone else's summary.json is theirs."""
    try:
        summary = json.loads(read_bytes(RunFolder(Path(run_dir)).summary, RunFolderError, MOST_SUMMARY_BYTES).decode("utf-8"))
    except (RunFolderError, ValueError, RecursionError):  # (not readable, not UTF-8, not JSON, too deep)
        return False
    return isinstance(summary, dict) and isinstance(summary.get("ctsim_version"), str) and isinstance(summary.get("reason"), str)


def _refuse(constant: str) -> None:
    raise ValueError(f"{constant} is no JSON number")


def _check(path: Path, summary: Any) -> None:
    if not isinstance(summary, dict):
        raise RunFolderError(path, None, "must be a JSON object (a run's summary), not " + type(summary).__name__)
    _fields(path, summary, TOP, OPTIONAL, "")
    robots = summary["robots"]
    if len(robots) > MOST_ROBOTS:
        raise RunFolderError(path, None, f"robots: {len(robots):,} robots, more than the {MOST_ROBOTS:,} a run may have")
    for i, robot in enumerate(robots):
        where = f"robots[{i}]."
        _fields(path, robot, ROBOT, ROBOT_OPTIONAL, where)
        for label, errors in robot["estimates"].items():
            if not isinstance(errors, dict):
                raise RunFolderError(path, None, f"{where}estimates.{label}: must be a table of numbers")
            for key, value in errors.items():
                _value(path, _MAYBE_NUMBER, value, f"{where}estimates.{label}.{key}")
        puts = robot.get("puts", [])
        if not isinstance(puts, list):
            raise RunFolderError(path, None, f"{where}puts: must be a list of times (s)")
        for k, time in enumerate(puts):
            _value(path, _NUMBER, time, f"{where}puts[{k}]")
        for label, name in robot.get("tum", {}).items():
            _value(path, _TEXT, name, f"{where}tum.{label}")
            trajectory_path(path.parent, name, f"{where}tum.{label}")


def _fields(path: Path, data: Any, required: dict[str, Any], optional: dict[str, Field], where: str) -> None:
    if not isinstance(data, dict):
        raise RunFolderError(path, None, f"{where.rstrip('.') or 'the summary'}: must be a table")
    for key, spec in {**required, **optional}.items():
        if key not in data:
            if key in required:
                raise RunFolderError(path, None, f"{where}{key}: missing")
            continue
        if isinstance(spec, dict):
            _fields(path, data[key], spec, {}, f"{where}{key}.")
        else:
            _value(path, spec, data[key], f"{where}{key}")


def _value(path: Path, field: Field, value: Any, key: str) -> None:
    try:
        field.check(value)
    except Problem as problem:
        raise RunFolderError(path, None, f"{key}: {problem.message}") from None


def trajectory_path(run_dir: Path, name: str, key: str = "tum") -> Path:
    """The path of a trajectory file named in summary.json: a plain file name inside the folder
    (RunFolderError for a name with a folder in it, `..`, or an absolute path)."""
    if not name or name in (".", "..") or "/" in name or "\\" in name or "\0" in name:
        raise RunFolderError(RunFolder(run_dir).summary, None, f"{key}: {name[:80]!r} is not a file name in the run folder")
    return run_dir / name


def trajectory_text(run_dir: Path, name: str, lines: int) -> str:
    """A trajectory file's text: a regular file in the folder, at most MOST_TRAJECTORY_BYTES, of
    which about `lines` lines at most, evenly spread, the first and the last among them, read a
    line at a time (a long run's figure needs no more points than it has pixels, and its file
    need not fit in memory)."""
    path = trajectory_path(run_dir, name)
    if not path.exists():
        raise RunFolderError(path, None, f"missing: {SUMMARY} names it, but the run folder has no such file")
    with open_regular(path, RunFolderError, MOST_TRAJECTORY_BYTES) as file:
        try:
            data, every = _every_line(file, lines)
        except OSError as err:
            raise RunFolderError(path, None, f"cannot read: {err.strerror or err}") from None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        line = data[: err.start].count(b"\n") + 1 if every == 1 else None  # (a line of those kept is not the file's)
        raise RunFolderError(path, line, "not a TUM trajectory (not text)") from None


def _every_line(file: BinaryIO, lines: int) -> tuple[bytes, int]:
    """Every k-th line of `file` and its last, k chosen so that at most about `lines` are kept
    (all where it has no more); and k."""
    total = sum(chunk.count(b"\n") for chunk in iter(lambda: file.read(1 << 24), b""))
    every = max(1, -(-total // max(lines, 1)))
    file.seek(0)
    if every == 1:  # (all of it: one read, not a line at a time)
        return file.read(), every
    kept, last = [], b""
    for k, line in enumerate(file):
        if k % every == 0:
            kept.append(line)
        last = line
    if kept and kept[-1] is not last:
        kept.append(last)
    return b"".join(kept), every
