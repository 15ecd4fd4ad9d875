"""Sweeps: many independent runs from a plan, on an engine, into a table that survives being killed.

    from sim.experiments import sweep
    table = sweep("noise.toml", "runs/noise")      # pandas DataFrame, one row per run

A row holds the run's settings, its outcome (reason, error, simulated time, goal, collisions,
distance), the odometry metrics per estimator as `<estimator>.<metric>` (e.g. `mouse.ate_rmse`)
and the wall time. Rows reach disk as runs finish; run the same sweep into the same folder
again and only the missing runs execute.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from contextlib import ExitStack, closing
from pathlib import Path
from typing import Any

import pandas as pd

from bots.odometry.user import name_of
from sim.analysis.run_folder import RunFolder
from sim.errors import UserError
from sim.experiments import store
from sim.experiments.api import Bot, Result, simulate
from sim.experiments.engines import Dask, Lost, Processes, Serial
from sim.experiments.plan import (
    Job,
    SpecError,
    SweepSpec,
    jobs,
    load_sweep,
    spec_from_dict,
)
from sim.experiments.progress import Progress
from sim.folder_lock import held
from sim.run.ending import Ending, Terminated

OUTCOME = ("reason", "error", "sim_time", "reached_goal", "goal_time", "fell", "collisions", "distance")
"""Outcome columns of every row, beside the settings and the metrics."""


def bot(settings: dict[str, Any]) -> Bot:
    """The robot a run's settings describe."""
    params = {k.removeprefix("params."): v for k, v in settings.items() if k.startswith("params.")}
    changes = {k.removeprefix("robot."): v for k, v in settings.items() if k.startswith("robot.")}
    return Bot(settings["controller"], params, settings["robot"], changes, noise=settings["noise"])


def outcome(result: Result) -> dict[str, Any]:
    """The outcome and metric columns of a finished run (its first robot)."""
    robot = result.robots[0]
    row = {
        "reason": result.reason,
        "error": result.error,
        "sim_time": float(result.time[-1]) if len(result.time) else 0.0,
        "reached_goal": robot.goal_time is not None,
        "goal_time": math.nan if robot.goal_time is None else float(robot.goal_time),
        "fell": bool(robot.fell),
        "collisions": int(robot.collisions),
        "distance": robot.distance,
    }
    for estimator, values in robot.metrics.items():
        row.update({f"{estimator}.{metric}": float(v) for metric, v in values.items()})
    return row


ESTIMATOR_ERRORS = "estimator_errors"
"""A row's column of the job's estimators that failed its run (`Job.estimators`): JSON, name -> the
run's error line; the row's outcome and metrics are of the run again without them."""


def execute(job: Job) -> dict[str, Any]:
    """Run one job and return its row; a run that raises becomes a row with reason 'error', a run
    that Ctrl-C or SIGTERM stopped re-raises them. A run that one of the job's own estimators
    failed runs again without it (`_without_failing`), so that the others' metrics count."""
    started = time.perf_counter()
    row: dict[str, Any] = {"run": job.index, "run_id": job.run_id, **job.settings}
    s = job.settings
    try:
        folder = Path(job.folder) if job.folder else None
        if folder is not None:
            folder.mkdir(parents=True, exist_ok=True)
        record = RunFolder(folder).recording if folder is not None and "recording" in job.keep else None

        def attempt(estimators: tuple[Any, ...]) -> Result:
            result = simulate(s["world"], bot(s), duration=s["duration"], dt=s["dt"], seed=s["seed"], until_goal=s["until_goal"], record=record,
                              estimators=estimators, step_timeout=job.step_timeout)
            if result.reason.signalled:  # a run cut short is no result: not kept, so a resumed sweep runs it again
                raise Terminated if result.reason is Ending.TERMINATED else KeyboardInterrupt
            return result

        with ExitStack() as isolation:  # (the isolated estimators' processes, ended after the run)
            result, failures = _without_failing(_estimators(job, isolation), attempt)
        row.update(outcome(result))
        if failures:
            row[ESTIMATOR_ERRORS] = json.dumps(failures)
        if folder is not None and "tum" in job.keep:
            _write_tum(result, folder)
    except Exception as err:  # a failing run is a result of the sweep, not the end of it
        row.update({name: None for name in OUTCOME}, reason=Ending.ERROR, error=f"{type(err).__name__}: {err}")
    row["wall_time_s"] = time.perf_counter() - started
    return row


def _estimators(job: Job, isolation: ExitStack) -> tuple[Any, ...]:
    """The job's estimators as its runs take them: their sources, or with `Job.isolate` each
    user's file made in processes of its own that end with `isolation`."""
    if not job.isolate:
        return job.estimators
    from sim.run.clock import STEP_TIMEOUT
    from sim.sandbox.isolated import estimator_source

    return tuple(estimator_source(source, job.step_timeout or STEP_TIMEOUT, isolation) for source in job.estimators)


def _without_failing(estimators: tuple[Any, ...], attempt: Callable[[tuple[Any, ...]], Result]) -> tuple[Result, dict[str, str]]:
    """`attempt` with `estimators`, again without each of them that ended a run (its first robot's
    own: the world draws every random number by robot and sensor, never by the set of estimators,
    so the others' runs are the runs they would have been without it); the last run and each
    dropped estimator's name with its run's error line."""
    failures: dict[str, str] = {}
    result = attempt(estimators)
    while estimators and result.reason is Ending.ERROR and result.raw.failed_estimator is not None:
        robot, name = result.raw.failed_estimator
        names = [name_of(e) for e in result.raw.robots[robot].estimators] if robot == 0 else []
        if name not in names or len(names) != len(estimators):  # (not one of the job's: the run's own failure)
            break
        failures[name] = str(result.error)
        estimators = estimators[: names.index(name)] + estimators[names.index(name) + 1 :]
        result = attempt(estimators)
    return result, failures


def _write_tum(result: Result, folder: Path) -> None:
    from sim.analysis.export import write_tum

    robot = result.robots[0]
    for label, poses in {"truth": robot.truth, **robot.estimates}.items():
        write_tum(folder / f"{label}.tum", result.time[: len(poses)], poses)


def lost_row(job: Job, lost: Lost) -> dict[str, Any]:
    """The row of a run whose worker kept dying."""
    return {"run": job.index, "run_id": job.run_id, **job.settings, **{name: None for name in OUTCOME}, "reason": Ending.ERROR, "error": f"run lost: {lost.message}", "wall_time_s": math.nan}


def check(planned: list[Job]) -> None:
    """Build every distinct world, robot and controller of a plan once, so that a mistake in the
    spec stops the sweep before anything runs (ValueError naming the run and the setting)."""
    from sim.experiments.api import world

    tried: set[str] = set()
    for job in planned:
        s = job.settings
        robot_part = {k: v for k, v in s.items() if k in ("robot", "controller", "noise") or k.startswith(("robot.", "params."))}
        for what, build in ((f"world {s['world']!r}", lambda s=s: world(s["world"])), (f"robot {robot_part}", lambda s=s: bot(s).setup())):
            if what not in tried:
                tried.add(what)
                try:
                    build()
                except (UserError, OSError) as err:
                    raise SpecError(f"run {job.index}, {what}: {err}") from None


def sweep(
    spec: str | Path | SweepSpec | dict,
    out: str | Path,
    runner: Serial | Processes | Dask | None = None,
    on_row: Callable[[dict[str, Any]], None] | None = None,
    progress: bool = True,
) -> pd.DataFrame:
    """Run every planned run not yet in `out` on `runner` (default: local processes, all cores),
    keeping each row as it finishes; the whole table. Ctrl-C (KeyboardInterrupt) and SIGTERM
    (`sim.run.ending.Terminated`, where a handler raises it, as `ctsim sweep` does) stop the runs in
    flight at once and re-raise, with every finished row kept: the same call resumes. `progress`:
    say on stderr how far it has got (`sim.experiments.progress`: a bar on a terminal, else a line
    every few seconds, and first how many runs a resumed sweep had done).

    >>> import tempfile
    >>> spec = {"base": {"world": "empty", "duration": 0.1}, "axes": {"seed": [0, 1]}}
    >>> with tempfile.TemporaryDirectory() as out:
    ...     table = sweep(spec, out, Serial(), progress=False)
    >>> sorted(table["seed"]), sorted(table["reason"])
    ([0, 1], ['duration', 'duration'])
    """
    if isinstance(spec, dict):
        spec = spec_from_dict(spec)
    elif not isinstance(spec, SweepSpec):
        spec = load_sweep(spec)
    out = Path(out)
    planned = jobs(spec, out)
    check(planned)
    with held(out, "sweep"):  # (a second sweep into `out` is refused: it would run every run twice)
        return run_jobs(planned, out, runner, on_row, progress)


def run_jobs(planned: list[Job], out: Path, runner: Serial | Processes | Dask | None = None, on_row: Callable[[dict[str, Any]], None] | None = None,
             progress: bool = True, what: str = "sweep") -> pd.DataFrame:
    """The planned jobs not yet in `out` run on `runner` as `sweep` runs them (its caller holds
    the folder; `what` names the work in the progress lines): `sweep`'s and `ctsim evaluate`'s."""
    finished = store.done(out)
    todo = [job for job in planned if job.run_id not in finished]
    owned = runner is None
    runner = runner or Processes()
    bar = Progress(len(planned), len(planned) - len(todo), "run", what) if progress else None
    try:
        with closing(runner.imap(execute, todo)) as outcomes:  # closed at once on Ctrl-C: the engine stops its workers
            for job, result in outcomes:
                row = lost_row(job, result) if isinstance(result, Lost) else result
                store.append(out, row)
                if on_row is not None:
                    on_row(row)
                if bar is not None:
                    bar.update(1)
    finally:
        if bar is not None:
            bar.close()
        if owned:
            runner.close()
    return store.compact(out)  # (not after Ctrl-C: the rows are safe in their parts, and the next call folds them)
