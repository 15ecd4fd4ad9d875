"""`ctsim evaluate`: estimators scored on the evaluation suite (`sim.experiments.suite`) beside
the shipped ones, into a results file others can check and merge.

The runs go through the sweep's machinery (`sim.experiments.sweeping.run_jobs`: local processes or
Dask, a row kept on disk as each run finishes, Ctrl-C keeps them and the same call resumes). The
results file (`results.json`) holds the suite's name and version, ctsim's version, each
scenario's hash, each estimator's source and the sha256 of its file, and every run's metrics; it
holds nothing of the machine or the hour, so the same suite, seeds and estimators give the same
file, byte for byte. `merge` joins files of the same suite version and scenario hashes, and
refuses any other.

    results = evaluate(VARIANTS["short"], ["my_filter.py:Filter"], "runs/evaluate-short")
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import stat
from collections.abc import Callable
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import sim
from sim import sanitize
from sim.errors import UserError
from sim.experiments.suite import SUITE_VERSION, Scenario, Variant
from sim.run.clock import STEP_TIMEOUT, made_in_time
from sim.run.ending import Ending, Terminated

FORMAT = "ctsim-evaluation"
FORMAT_VERSION = 1
"""What a results file is, and the version of its layout (not of the suite: `SUITE_VERSION`)."""
RESULTS = "results.json"
METRICS = ("ate_rmse", "rpe_translation", "rpe_rotation", "final_position_error", "final_heading_error", "nees_final", "path_length")
"""Per run and estimator, what the results file keeps (`sim.analysis.metrics.Metrics`)."""
SHIPPED = ("localiser",)
"""Shipped estimators scored beside the run's defaults (encoders, firmware, mouse, fused) in every run."""
TRIAL_S = 0.3
"""Simulated seconds of the trial run each submitted estimator passes before the suite starts: a
constructor, `reset` or first `update` that raises is one line then, not a column of failed runs."""


class EvaluationError(UserError):
    """An estimator that cannot be scored, or a results file that cannot be read or merged."""


class NotWritten(Exception):
    """The suite's runs are done and kept in the run table, but the results file could not be
    written (a full disk, a folder planted at its name: `__cause__`); `results` holds them."""

    def __init__(self, results: dict[str, Any]):
        super().__init__("the results file could not be written")
        self.results = results


@dataclass(frozen=True)
class Submitted:
    """An estimator to score: its source as `ctsim evaluate` was given it, that source with the
    file's absolute path (for worker processes), its name and what it is (`sha256:` of its file)."""

    source: str
    located: str
    name: str
    identity: str


def submitted(sources: list[str], step_timeout: float | None = STEP_TIMEOUT, isolate: bool = False) -> list[Submitted]:
    """Each source loaded, built, named and tried on a short run (each call of it under
    `step_timeout`, as in the suite's runs; with `isolate` in processes of its own, never in this
    one); EvaluationError (one line) for a missing file, a class that cannot be made or fails on
    its first steps (raises, leaves, overruns, a bad pose or covariance), or a taken name. Ctrl-C
    or SIGTERM during the trial stops it as it stops the suite."""
    from bots.odometry.user import SHIPPED as BY_NAME
    from bots.odometry.user import beside_defaults, load, name_of
    from sim.experiments.api import Bot, robot, simulate
    from sim.sandbox.isolated import estimator_source

    found = []
    for source in sources:
        if source in BY_NAME and not Path(source).is_file():
            found.append(Submitted(source, source, source, "shipped"))
            continue
        file, _, cls = source.partition(":") if not Path(source).is_file() else (source, "", "")
        path = Path(file).resolve()  # (before its code runs: code that changes the current folder moves nothing)
        if not isolate:
            with made_in_time(step_timeout):
                load(source)  # (a missing file or class: one line of its own)
        located = str(path) + (f":{cls}" if cls else "")
        identity = "sha256:" + hashlib.sha256(path.read_bytes()).hexdigest()
        found.append(Submitted(source, located, "", identity))
    shipped = [s for s in SHIPPED if s not in sources]
    with ExitStack() as isolation:  # (the isolated estimators' processes, ended after the trials)
        given = [estimator_source(s.located, step_timeout or STEP_TIMEOUT, isolation) if isolate else s.located for s in found]
        with made_in_time(step_timeout):
            made = beside_defaults(robot("ctbot"), [*shipped, *given])  # (names taken or not words: refused here)
        found = [Submitted(s.source, s.located, name_of(e), s.identity) for s, e in zip(found, made[len(shipped):])]
        for entry, estimator in zip(found, given):
            trial = simulate("maze", Bot("solve_maze"), duration=TRIAL_S, seed=0, estimators=[estimator], step_timeout=step_timeout)
            if trial.reason.signalled:
                raise Terminated if trial.reason is Ending.TERMINATED else KeyboardInterrupt
            if trial.error:
                raise EvaluationError(f"estimator {entry.source}: {trial.error}")
    return found


def evaluate(variant: Variant, sources: list[str], out: str | Path, runner: Any = None, progress: bool = True,
             on_row: Callable[[dict[str, Any]], None] | None = None, step_timeout: float | None = STEP_TIMEOUT, isolate: bool = False) -> dict[str, Any]:  # fmt: skip
    """Score the estimators of `sources` (`FILE.py[:CLASS]`, or a shipped one by name) beside the
    shipped ones on every run of `variant`, on `runner` (an engine of `sim.experiments.engines`;
    default local processes), resuming what `out` holds; the results (`results_of`), also
    written to `out/results.json` (NotWritten, holding them, where it cannot be). A call of an estimator's code that takes longer than
    `step_timeout` seconds (wall clock; None: no limit) fails its run, as in `ctsim run`. With
    `isolate`, the estimators' files run in processes of their own, isolated by the operating
    system (`ctsim run --isolate`'s sandbox), never in this process or the engine's workers."""
    from sim.experiments.sweeping import run_jobs
    from sim.folder_lock import held

    entries = submitted(sources, step_timeout, isolate)
    out = Path(out)
    planned = variant.jobs([*(s for s in SHIPPED if s not in sources), *(e.located for e in entries)],
                           [*(s for s in SHIPPED if s not in sources), *(e.identity for e in entries)], step_timeout, isolate)  # fmt: skip
    with held(out, "evaluate"):
        table = run_jobs(planned, out, runner, on_row, progress, what="evaluate")
        ours = table[table["run_id"].isin({job.run_id for job in planned})]  # (not the rows of an estimator's file as it was before)
        results = results_of(variant, entries, ours.to_dict("records"))
        try:
            write_results(results, out / RESULTS)
        except (OSError, UserError) as err:  # (NotAFileOfItsOwn: a folder at its name)
            raise NotWritten(results) from err
    return results


def _number(value: Any) -> float | None:
    """A metric for JSON: a float, or None where it is undefined (nan) or missing."""
    if value is None:
        return None
    value = float(value)
    return value if math.isfinite(value) else None


def results_of(variant: Variant, entries: list[Submitted], rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The results file's content from a suite's finished rows (`sim.experiments.sweeping` rows):
    runs in the suite's order, each estimator's metrics, and for a run that failed its error
    against whoever failed it (`_blamed`). An estimator that failed a run is blamed for it by name
    (`ESTIMATOR_ERRORS`: the run went on without it), the others keep their metrics of that run."""
    from sim.experiments.sweeping import ESTIMATOR_ERRORS

    names = sorted({c.rpartition(".")[0] for row in rows for c in row if c.endswith(".ate_rmse")})
    order = {(s.name, seed): k for k, (s, seed) in enumerate((s, seed) for s in variant.scenarios for seed in variant.seeds)}
    runs = []
    for row in sorted(rows, key=lambda r: order[(r["scenario"], int(r["seed"]))]):
        failed = row["reason"] == Ending.ERROR
        dropped = json.loads(row[ESTIMATOR_ERRORS]) if isinstance(row.get(ESTIMATOR_ERRORS), str) else {}  # (NaN in a table of rows without)
        run = {"scenario": row["scenario"], "seed": int(row["seed"]),
               "metrics": {} if failed else {n: {m: _number(row.get(f"{n}.{m}")) for m in METRICS} for n in names
                                             if n not in dropped and row.get(f"{n}.ate_rmse") is not None}}  # fmt: skip
        submitted_names = {e.name for e in entries}
        blamed = {name if name in submitted_names else "run": _plain_error(entries, error) for name, error in dropped.items()}
        if failed:
            blamed |= _blamed(entries, str(row["error"]))
        if blamed:
            run["failed"] = blamed
        runs.append(run)
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "suite": variant.name,
        "suite_version": SUITE_VERSION,
        "ctsim_version": sim.__version__,
        "seeds": list(variant.seeds),
        "scenarios": {s.name: {"hash": digest, **_about(s)} for s, digest in zip(variant.scenarios, variant.hashes().values())},
        "estimators": {e.name: {"source": Path(e.source.partition(":")[0]).name + (":" + e.source.partition(":")[2] if ":" in e.source else ""),
                                "identity": e.identity} for e in entries},  # fmt: skip
        "runs": runs,
    }


def _about(scenario: Scenario) -> dict[str, Any]:
    """A scenario's settings as its results file gives them (beside its hash), as JSON reads them back."""
    return {"world": scenario.world, "controller": scenario.controller, "params": dict(scenario.params), "noise": scenario.noise,
            "duration_s": scenario.duration, "until_goal": scenario.until_goal}


def _blamed(entries: list[Submitted], error: str) -> dict[str, str]:
    """Who failed a run: the submitted estimator its error names (the run loop's `estimator 'NAME'`),
    else every submitted one (the shipped ones do not fail), else the run itself. The error names
    the estimators' files by their names alone (as the results file's sources do: nothing of the
    machine's folders)."""
    named = [e for e in entries if f"estimator {e.name!r}" in error]
    error = _plain_error(entries, error)
    return {e.name: error for e in named or entries} or {"run": error}


def _plain_error(entries: list[Submitted], error: str) -> str:
    """A run's error as a results file holds it: the estimators' files by their names alone (as the
    results file's sources: nothing of the machine's folders), one line, escapes as text, cut."""
    for entry in entries:
        folder = str(Path(entry.located.partition(".py:")[0]).parent)
        error = error.replace(folder + os.sep, "") if entry.identity != "shipped" else error
    return sanitize.name(error, 2000)


def failed_runs(results: dict[str, Any]) -> list[dict[str, Any]]:
    """Every failed run of a results file, a row per estimator it blames: the scenario, the seed,
    the estimator, its source (the file's name and class as given; a shipped one's or the run's own
    name) and the error, in the suite's order."""
    return [{"scenario": run["scenario"], "seed": run["seed"], "estimator": who, "source": results["estimators"].get(who, {}).get("source", who), "error": message}
            for run in results["runs"] for who, message in run.get("failed", {}).items()]  # fmt: skip


def write_results(results: dict[str, Any], path: Path) -> Path:
    """The results as JSON, keys sorted, two-space indents, floats as Python writes them back
    exactly: the same results are the same bytes."""
    from sim.out_files import write_text

    return write_text(path, json.dumps(results, indent=2, sort_keys=True, allow_nan=False) + "\n")


MAX_RESULTS_BYTES = 64 * 2**20
"""Largest results file `read_results` reads: the full suite with a class of a hundred estimators
beside the shipped ones is a few MB."""
_KEYS = ("format", "format_version", "suite", "suite_version", "ctsim_version", "seeds", "scenarios", "estimators", "runs")
_RUN_KEYS = {"scenario", "seed", "metrics", "failed"}
_VERSIONS = re.compile(r"[0-9A-Za-z.+!_-]{1,40}(, [0-9A-Za-z.+!_-]{1,40}){0,99}")
"""ctsim's version as a results file may give it (merged files: several, comma-separated)."""
_HASH = re.compile(r"[0-9a-f]{64}")


def read_results(path: str | Path) -> dict[str, Any]:
    """A results file, checked to be one of this format and of this ctsim's suite version, and to
    hold what `results_of` writes and nothing else (`_shape_problem`): EvaluationError, one line
    naming the file, for anything else (not a regular file, larger than MAX_RESULTS_BYTES, not
    UTF-8 JSON, a key twice, NaN, nested or numbered beyond what Python reads)."""
    path = Path(path)
    text = _read_text(path)
    try:
        results = json.loads(text, object_pairs_hook=_once_each, parse_constant=_no_constant)
    except (ValueError, RecursionError) as err:  # (a JSONDecodeError; an integer of thousands of digits; nesting too deep)
        said = "nested too deeply" if isinstance(err, RecursionError) else f"{type(err).__name__}: {err}"
        raise EvaluationError(f"{path}: not a results file of ctsim evaluate ({said})") from None
    if not isinstance(results, dict) or results.get("format") != FORMAT or any(k not in results for k in _KEYS):
        raise EvaluationError(f"{path}: not a results file of ctsim evaluate")
    if type(results["format_version"]) is not int or results["format_version"] != FORMAT_VERSION or results["suite_version"] != SUITE_VERSION:
        raise EvaluationError(f"{path}: suite version {str(results['suite_version'])[:40]!r} (file format {str(results['format_version'])[:40]!r}); "
                              f"this ctsim scores suite version {SUITE_VERSION!r} (format {FORMAT_VERSION}): run the estimator again with this ctsim")  # fmt: skip
    problem = _shape_problem(results)
    if problem:
        raise EvaluationError(f"{path}: not a results file of ctsim evaluate: {problem}")
    return results


def _read_text(path: Path) -> str:
    """The text of a results file: a regular file (through a link too) of at most
    MAX_RESULTS_BYTES, opened without waiting on a pipe; EvaluationError otherwise."""
    from sim.out_files import kind

    try:
        descriptor = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as err:
        raise EvaluationError(f"{path}: cannot be read ({err.strerror or err})") from None
    info = os.fstat(descriptor)
    mode, size = info.st_mode, info.st_size
    if not stat.S_ISREG(mode):
        os.close(descriptor)
        raise EvaluationError(f"{path}: {kind(mode)}, not a results file of ctsim evaluate (a regular file)")
    with os.fdopen(descriptor, "rb") as file:
        data = file.read(MAX_RESULTS_BYTES + 1) if size <= MAX_RESULTS_BYTES else b""
    if size > MAX_RESULTS_BYTES or len(data) > MAX_RESULTS_BYTES:
        raise EvaluationError(f"{path}: {max(size, len(data)):,} bytes, more than a results file of ctsim evaluate holds ({MAX_RESULTS_BYTES:,})")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise EvaluationError(f"{path}: not a results file of ctsim evaluate (not UTF-8: {err.reason} at byte {err.start})") from None


def _once_each(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object whose keys are all different (else ValueError: a file edited by hand, whose
    reader would otherwise keep the last of two values unsaid)."""
    table = dict(pairs)
    if len(table) != len(pairs):
        twice = next(key for k, (key, _) in enumerate(pairs) if key in dict(pairs[:k]))
        raise ValueError(f"the key {twice[:100]!r} twice in one object")
    return table


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is no number a results file holds")


def _plain(text: Any, limit: int = 300) -> bool:
    """Text a results file may hold where ctsim prints or writes it: no control, format or lone
    surrogate character (`sanitize.escape` leaves it as it is), at most `limit` characters."""
    return isinstance(text, str) and len(text) <= limit and sanitize.escape(text) == text


def _shape_problem(results: dict[str, Any]) -> str | None:
    """What in a results file of the right version is not as `results_of` writes one (None: nothing):
    a file edited by hand or by another program is refused in one line, never half read. Its
    suite, seeds and scenarios are those of this suite version's variant of that name; every
    estimator named is a shipped one or listed with its source; every metric a finite number
    (non-negative but the heading error) or null."""
    from bots.odometry.user import NAME
    from sim.experiments.suite import VARIANTS

    unknown = sorted(set(results) - set(_KEYS), key=str)
    if unknown:
        return f"unknown key {unknown[0][:100]!r}"
    if not (isinstance(results["ctsim_version"], str) and _VERSIONS.fullmatch(results["ctsim_version"])):
        return "'ctsim_version' must be a version (letters, digits, '.', '+', '-')"
    variant = VARIANTS.get(results["suite"]) if isinstance(results["suite"], str) else None
    if variant is None:
        return f"'suite' must be one of {', '.join(VARIANTS)}"
    seeds, scenarios, estimators, runs = results["seeds"], results["scenarios"], results["estimators"], results["runs"]
    if not (isinstance(seeds, list) and all(type(seed) is int for seed in seeds) and seeds == list(variant.seeds)):
        return f"'seeds' must be the {variant.name} suite's, {list(variant.seeds)}"
    expected = {s.name: _about(s) for s in variant.scenarios}
    if not (isinstance(scenarios, dict) and set(scenarios) == set(expected)):
        return f"'scenarios' must be the {variant.name} suite's, {', '.join(expected)}"
    for name, about in scenarios.items():
        if not (isinstance(about, dict) and isinstance(about.get("hash"), str) and _HASH.fullmatch(about["hash"])
                and {k: v for k, v in about.items() if k != "hash"} == expected[name]):  # fmt: skip
            return f"scenario {name}: its settings must be the suite's, with its hash (64 hex digits)"
    if len({about["hash"] for about in scenarios.values()}) != len(scenarios):
        return "two scenarios with the same hash"
    if not (isinstance(estimators, dict) and all(isinstance(name, str) and NAME.fullmatch(name) and isinstance(v, dict) and set(v) == {"source", "identity"}
                                                  and _plain(v["source"]) and _plain(v["identity"], 100) for name, v in estimators.items())):  # fmt: skip
        return "'estimators' must map each estimator (a plain word) to its source and identity (plain text)"
    if not (isinstance(runs, list) and all(isinstance(run, dict) and set(run) <= _RUN_KEYS and type(run.get("seed")) is int for run in runs)):
        return "'runs' must be a list of runs, each its scenario, seed (a whole number), metrics and what failed"
    order = list(dict.fromkeys(run.get("scenario") for run in runs))  # (the suite's order: the file's keys are sorted)
    if order != list(expected) or [(r.get("scenario"), r.get("seed")) for r in runs] != [(scenario, seed) for scenario in order for seed in seeds]:
        return "'runs' must hold every scenario's runs, seed by seed, in the suite's order"
    scored = set(estimators) | shipped_names()
    for run in runs:
        metrics, failed = run.get("metrics"), run.get("failed", {})
        where = f"run {run['scenario']} seed {run['seed']}"
        if not (isinstance(metrics, dict) and isinstance(failed, dict)):
            return f"{where}: 'metrics' and 'failed' must be tables"
        if not (set(metrics) <= scored and set(failed) <= set(estimators) | {"run"}):
            return f"{where}: an estimator that is neither shipped nor listed in 'estimators'"
        if not all(isinstance(values, dict) and set(values) == set(METRICS) and all(_metric(m, v) for m, v in values.items()) for values in metrics.values()):
            return f"{where}: each estimator's metrics must be {', '.join(METRICS)} (finite numbers, not negative but the heading error, or null)"
        if not all(_plain(message, 4000) for message in failed.values()):
            return f"{where}: 'failed' must give each estimator's error as plain text"
    return None


def _metric(name: str, value: Any) -> bool:
    """Whether `value` can be metric `name` of a run: null (undefined), or a finite number, not
    negative but the heading error (wrapped to at most pi either way)."""
    if value is None:
        return True
    if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
        return False
    return abs(value) <= math.pi + 1e-9 if name == "final_heading_error" else value >= 0


def shipped_names() -> set[str]:
    """The estimators every run scores beside the submitted ones: the c't-Bot's defaults and SHIPPED."""
    from bots.odometry.defaults import default_estimators
    from bots.odometry.user import name_of
    from sim.experiments.api import robot

    return {name_of(e) for e in default_estimators(robot("ctbot"))} | set(SHIPPED)


def merge(results: list[dict[str, Any]], names: list[str] | None = None) -> dict[str, Any]:
    """Results files of the same suite, version, seeds and scenario hashes joined into one table:
    every estimator of each, every run's metrics side by side. EvaluationError where they differ,
    where two files give the same estimator different metrics (another ctsim version, or two
    estimators of one name), or where one estimator name stands for two different files."""
    names = names or [f"file {k + 1}" for k in range(len(results))]
    first, merged = results[0], json.loads(json.dumps(results[0]))
    for other, name in zip(results[1:], names[1:]):
        for key in ("suite", "suite_version", "seeds"):
            if other[key] != first[key]:
                raise EvaluationError(f"{name}: {key} {other[key]!r}, {names[0]}: {first[key]!r}: only results of the same suite merge")
        hashes = {s: v["hash"] for s, v in other["scenarios"].items()}
        if hashes != {s: v["hash"] for s, v in first["scenarios"].items()}:
            differ = sorted(s for s in {*hashes, *first["scenarios"]} if hashes.get(s) != first["scenarios"].get(s, {}).get("hash"))
            raise EvaluationError(f"{name}: scenario hashes differ from {names[0]}'s ({', '.join(differ)}): the runs are not the same runs")
        for estimator, about in other["estimators"].items():
            if merged["estimators"].setdefault(estimator, about)["identity"] != about["identity"]:
                raise EvaluationError(f"{name}: estimator {estimator!r} is another file than in an earlier results file; rename one")
        for run, theirs in zip(merged["runs"], other["runs"]):
            if (run["scenario"], run["seed"]) != (theirs["scenario"], theirs["seed"]):
                raise EvaluationError(f"{name}: its runs are not the suite's runs in order")
            for estimator, values in theirs["metrics"].items():
                if run["metrics"].setdefault(estimator, values) != values:
                    raise EvaluationError(f"{name}: {estimator} scored differently in {run['scenario']} seed {run['seed']} "
                                          f"(ctsim {other['ctsim_version']} there, {first['ctsim_version']} in {names[0]}): merge results of one ctsim version")  # fmt: skip
            if theirs.get("failed"):
                run.setdefault("failed", {}).update(theirs["failed"])
    if len({r["ctsim_version"] for r in results}) == 1:
        return merged
    merged["ctsim_version"] = ", ".join(sorted({r["ctsim_version"] for r in results}))
    return merged
