"""A run's folder: made (and an earlier run's files cleared), locked, and filled with the summary,
trajectories, figures and report; the end-of-run table."""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path
from typing import Any

from bots.schema import file_stem
from sim import sanitize
from sim.analysis.run_folder import RunFolder
from sim.analysis.summary import goal_note, summarize, write_json
from sim.cli.observers import StopOnSignal
from sim.cli.options import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_TERMINATED, UsageError
from sim.folder_lock import LOCK, hold
from sim.out_files import NotAFileOfItsOwn, tallied
from sim.run.ending import Ending

START = Path.cwd()
"""The folder ctsim started in: a relative --out is taken from here, so that a controller that
changes the current folder when it loads cannot move the run's folder."""


def out_dir(out: Path | None, world: str, controller: str) -> Path:
    if out is None:
        stamp = time.strftime("%Y%m%d-%H%M%S")
        out = Path("runs") / f"{file_stem(Path(world).stem) or 'world'}-{file_stem(Path(controller.split(':')[0]).stem) or 'run'}-{stamp}"
    out = START / out
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise UsageError(f"{out}: cannot make the run's folder: {err.strerror or err}") from None
    _lock(out)
    for stale in _earlier_run(out):
        stale.unlink(missing_ok=True)
    return out


def _earlier_run(out: Path) -> list[Path]:
    """The files an earlier run wrote into `out` (what its summary.json names, and the files every
    run writes, `RunFolder.fixed`), removed before a new run writes there so that nothing stale is
    left beside its results; UsageError for a folder of other files, which ctsim leaves alone."""
    from sim.analysis.run_folder import RunFolderError, read_summary, written_by_ctsim

    present = [p for p in out.iterdir() if p.name != LOCK]
    if not present:
        return []
    try:
        summary = read_summary(out)
    except RunFolderError:
        summary = None
    if summary is None:
        if not written_by_ctsim(out):
            names = ", ".join(sorted(sanitize.name(p.name) for p in present)[:3])
            raise UsageError(f"--out {out} holds files that no ctsim run wrote ({names}{', ...' if len(present) > 3 else ''}): "
                             "give a new or empty folder, or the folder of an earlier run")
        return list(RunFolder(out).fixed)  # (an earlier run cut short: its fixed files only)
    named = [out / name for robot in summary["robots"] for name in robot.get("tum", {}).values()]
    return [*RunFolder(out).fixed, *named, *(p.with_suffix(".csv") for p in named)]


held: list[Any] = []  # the folders this command holds (`sim.folder_lock.Hold`), freed when it ends


def _lock(out: Path) -> None:
    """Hold `out` for this run (`sim.folder_lock`): a second run into it is refused."""
    handle = hold(out, "run")
    if handle is not None:
        held.append(handle)


def finish(result, out: Path, options: dict[str, Any], report: bool = True, metrics: dict[str, dict[str, dict]] | None = None,
           stop: StopOnSignal | None = None, recording_error: str | None = None, export_rate: float | None = None) -> int:
    """Write summary.json (first: it holds the figures and is small), TUM/CSV trajectories and
    figures of a run; print the table and the files; the exit status (EXIT_STATUSES). A full
    disk or an I/O error ends it with one line and exit 1, having written what fit. `metrics`:
    robot -> estimator -> metrics as a dict, where the caller has them already (else they are
    computed here). With `stop`, a signal received so far skips the figures, one received while
    they are drawn stops them, and either sets the status. `recording_error`: why the recording
    is incomplete (an I/O error too). `export_rate`: samples per second in the TUM and CSV files
    (None: every sample)."""
    folder = RunFolder(out)
    summary = summarize(result, options, metrics)
    with tallied() as tally:  # (every file written, in order: the list below, also after a failure half-way)
        try:
            write_json(folder.summary, summary)
            write_trajectories(result, out, summary, export_rate)
            write_json(folder.summary, summary)  # again, now naming the TUM files
            if report and len(result) and stop is not None and stop.received is not None:
                print(f"ctsim: figures skipped after the signal; `ctsim report {sanitize.name(str(out), 1000)}` draws them", file=sys.stderr)
            elif report and len(result):
                from sim.views.figures import report_run_dir

                if stop is not None:
                    stop.phase = "draw"
                try:
                    report_run_dir(out)
                except KeyboardInterrupt:
                    print(f"ctsim: figures stopped by the signal; `ctsim report {sanitize.name(str(out), 1000)}` draws them", file=sys.stderr)
            from sim.web.report import write_run_report

            write_run_report(out)
        except (OSError, NotAFileOfItsOwn) as err:  # (a full disk; a folder or link planted at a file's name while it ran)
            kept = ", ".join(sanitize.name(p.name) for p in _written(folder, tally)) or "nothing"
            said = sanitize.name(err.strerror if isinstance(err, OSError) and err.strerror else str(err), 1000)
            print(f"ctsim: error: writing the run's results into {sanitize.name(str(out), 1000)}: {said} (written: {kept})", file=sys.stderr)
            return EXIT_FAILED
    print(table(summary))
    for note in getattr(result, "notes", ()):  # what the run's guards put back (`sim.guards`)
        print(f"ctsim: note: {sanitize.name(note, 2000)}", file=sys.stderr)
    for log in result.robots:  # what a general chassis did other than asked (projected twists)
        for message, count in log.notes.values():
            print(f"ctsim: note: {sanitize.name(f'{log.name}: {message}', 2000)} ({count} step{'s' if count != 1 else ''} like it)", file=sys.stderr)
    print("wrote:")
    for path in _written(folder, tally):
        print(f"  {sanitize.name(str(path), 1000)}")
    if recording_error is not None:
        print(f"ctsim: error: the recording is incomplete: {sanitize.name(recording_error, 2000)}", file=sys.stderr)
        return EXIT_FAILED
    if result.reason == Ending.ERROR:
        print(f"ctsim: run stopped: {sanitize.name(result.error, 2000)}", file=sys.stderr)
        return EXIT_FAILED
    if isinstance(result.reason, Ending) and result.reason.signalled:
        print(f"ctsim: {result.error}; partial results written to {sanitize.name(str(out), 1000)}", file=sys.stderr)
        return EXIT_INTERRUPTED if result.reason is Ending.INTERRUPTED else EXIT_TERMINATED
    return (stop.status() if stop is not None else None) or 0


def _written(folder: RunFolder, tally: list[Path]) -> list[Path]:
    """The files a run wrote: its recording (written by rerun as the run went, where it is a file)
    and those `tally` holds (`sim.out_files.tallied`), each once, in the order first written."""
    recording = [folder.recording] if folder.recording.is_file() and not folder.recording.is_symlink() else []
    return list(dict.fromkeys([*recording, *tally]))


def write_trajectories(result, out: Path, summary: dict[str, Any], export_rate: float | None = None) -> list[Path]:
    """run.parquet (every sample: poses and readings), truth.tum and <estimate>.tum (prefixed with
    the robot name when there are several) and the same as CSV, at `export_rate` samples per second
    (None: all); records the file names in the summary for `ctsim report`."""
    from sim.analysis.export import write_parquet, write_run

    every = max(1, round(1 / (export_rate * result.dt))) if export_rate else 1
    written = [write_parquet(result, RunFolder(out).samples)]
    summary["parquet"], summary["export_every"] = written[0].name, every
    tums = write_run(result, out, prefix=len(result.robots) > 1, with_csv=True, every=every)
    for entry in summary["robots"]:
        entry["tum"] = {label: path.name for label, path in tums[entry["name"]].items()}
        written += [path for tum in tums[entry["name"]].values() for path in (tum, tum.with_suffix(".csv"))]
    return written


def _nees(errors: dict[str, Any]) -> str:
    """An estimate's NEES at the run's end for the table: '-' without a covariance ('nees_defined'
    missing) or where it is degenerate."""
    value = errors.get("nees_final")
    return "-" if value is None or not math.isfinite(value) else f"{value:.3g}"


NEES_NOTE = ("NEES end: the run's normalised error at its end, one draw of chi-square(3) for a consistent estimate (95 % in {low:.2f}-{high:.2f}); "
             "judge consistency over seeds (`ctsim sweep report`, docs/odometry.md). '-': no covariance, or a degenerate one")
"""The table's note on its NEES column."""


def _columns(rows: list[list[str]], left: int) -> list[str]:
    """Rows of cells as lines, each column as wide as its widest cell and two spaces apart (no
    number runs into the next), the first `left` columns left-aligned, the others right-aligned."""
    widths = [max(len(row[k]) for row in rows if k < len(row)) for k in range(max(map(len, rows)))]
    return ["  ".join(cell.ljust(widths[k]) if k < left else cell.rjust(widths[k]) for k, cell in enumerate(row)).rstrip() for row in rows]


def table(summary: dict[str, Any]) -> str:
    """The short end-of-run table: per robot distance and collisions, per estimate its errors."""
    from sim.analysis.nees import interval

    reached = [sanitize.name(robot["name"], 40) for robot in summary["robots"] if robot["goal_time"] is not None]
    outcome = {
        Ending.GOAL: f"goal reached at {summary['time']:.1f} s by {', '.join(reached)}", Ending.DURATION: "time limit reached",
        Ending.DONE: "done (every controller said it is done)", Ending.QUIT: "quit (window closed)",
    }.get(summary["reason"], summary["reason"])  # fmt: skip
    if summary["reason"] == Ending.DURATION and reached:
        outcome = f"goal reached by {', '.join(reached)}, ran on to the time limit"
    elif summary["reason"] == Ending.DURATION and any(robot.get("goal") for robot in summary["robots"]):
        outcome = f"time limit reached, goal not reached in {summary['time']:g} s"
    elif summary["reason"] == Ending.DURATION:
        outcome = "time limit reached (this world has no goal)"
    rows = [["robot", "estimate", "distance m", "collisions", "final err m", "ATE RMS m", "final hdg °", "NEES end"]]
    notes = []
    for robot in summary["robots"]:
        said = [note for note in ("fell into a hole" if robot["fell"] else "", goal_note(robot),
                                  f"controller: {robot['status']}" if robot.get("status") not in (None, "running", "goal reached") else "") if note]  # fmt: skip
        rows.append([sanitize.name(robot["name"], 40), "", f"{robot['distance']:.3f}", f"{robot['collisions']:d}"])
        notes.append((len(rows) - 1, ", ".join(said)))
        for name, errors in robot["estimates"].items():
            rows.append(["", name, "", "", f"{errors['final_position_error']:.4f}", f"{errors['ate_rmse']:.4f}", f"{math.degrees(errors['final_heading_error']):.2f}", _nees(errors)])
    lines = _columns(rows, left=2)
    for row, note in notes:
        if note:
            lines[row] += "   " + note
    low, high = interval(1)
    said = {name: caveat for robot in summary["robots"] for name, caveat in robot.get("caveats", {}).items()}
    return "\n".join([f"{sanitize.name(summary['world']['name'])}, seed {summary['seed']}, noise {summary.get('noise', 'none')}, "
                      f"{summary['time']:.2f} s simulated: {outcome}", *lines, NEES_NOTE.format(low=low, high=high),
                      *(["where each covariance is known not to hold (docs/odometry.md):"] if said else []),
                      *(f"  {name}: {caveat}" for name, caveat in said.items())])
