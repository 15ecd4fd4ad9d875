"""`ctsim evaluate`: your estimators scored on the evaluation suite beside the shipped ones, and
results files of several people merged into one table."""

from __future__ import annotations

import argparse
import sys
import textwrap
from collections.abc import Callable
from pathlib import Path

from sim import sanitize
from sim.cli.options import EXIT_FAILED, UsageError, add_engine_options, add_step_timeout_option, engine_of


def add_parser(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    from sim.experiments.suite import SUITE_VERSION, VARIANTS

    evaluate = commands.add_parser(
        "evaluate",
        help="score odometry estimators on the fixed evaluation suite beside the shipped ones (ATE, RPE, final error, NEES), ranked",
        description=textwrap.fill(f"Run the evaluation suite (version {SUITE_VERSION}; docs/odometry.md, 'Evaluation') with your estimators (FILE.py[:CLASS], "
        "as `ctsim run --estimator`) beside the shipped ones, on local processes (default, all cores) or Dask, and rank them. "
        "Writes results.json (every run's metrics, the suite's version and scenario hashes: to check, share and merge), "
        "scores.csv, ranking.csv and report.html into DIR; a finished run is kept as it ends, so Ctrl-C and the same command again resume. "
        "`ctsim evaluate --merge A.json B.json ...` joins results files of the same suite into one table.", 100)
        + "\n\nsuites:\n" + "\n".join(f"  {name:6} {v.about}" for name, v in VARIANTS.items()),
    )
    evaluate.add_argument("estimators", nargs="*", metavar="FILE.py[:CLASS]", help="your estimators (none: the shipped ones alone)")
    evaluate.add_argument("--suite", choices=tuple(VARIANTS), default="short", help="which variant of the suite (default: short)")
    evaluate.add_argument("--merge", nargs="+", type=Path, metavar="RESULTS.json", help="join these results files instead of running anything")
    evaluate.add_argument("--out", type=Path, metavar="DIR", help="folder of the results (default: runs/evaluate-<suite>, runs/evaluate-merged with --merge)")
    add_engine_options(evaluate)
    add_step_timeout_option(evaluate, "an estimator's reset, update or pose that takes longer (wall clock) fails its run as the estimator's error")
    evaluate.add_argument("--isolate", action="store_true",
                          help="run the estimator files in processes of their own (`ctsim run --isolate`'s sandbox), never in ctsim's: for code you did not "
                          "write, e.g. students' (docs/odometry.md, 'Evaluation'); they may import numpy, the standard library and bots.commands")  # fmt: skip
    evaluate.set_defaults(handler=cmd_evaluate)


def cmd_evaluate(args: argparse.Namespace) -> int:
    import numpy as np

    from sim.cli.output import START
    from sim.experiments.evaluation import RESULTS, NotWritten, evaluate, merge, read_results, write_results
    from sim.experiments.scores import terminal
    from sim.experiments.suite import variant
    from sim.out_files import tallied
    from sim.web.evaluation import write_all

    if args.merge and args.estimators:
        raise UsageError("--merge joins results files; run the estimators without it first")
    # (from the folder ctsim started in: an estimator that changes the current folder cannot move the results)
    out = START / (args.out or Path("runs") / ("evaluate-merged" if args.merge else f"evaluate-{args.suite}"))
    with tallied() as tally:  # (every file written: the list below, also when writing failed half-way)
        failure: Exception | None = None
        if args.merge:
            results = merge([read_results(path) for path in args.merge], [str(path) for path in args.merge])
            out.mkdir(parents=True, exist_ok=True)
            failure = _writing(lambda: write_results(results, out / RESULTS))
        else:
            runner = engine_of(args)
            try:
                results = evaluate(variant(args.suite), args.estimators, out, runner, step_timeout=args.step_timeout, isolate=args.isolate)
            except NotWritten as err:  # (the runs are done and kept; their results file could not be written)
                results, failure = err.results, err.__cause__
            finally:
                runner.close()
        with np.errstate(over="ignore", invalid="ignore"):  # (metrics near the largest float: their means inf, said so, not warned of)
            tables = _writing(lambda: write_all(results, out))  # (also when the results file could not be written)
            table = terminal(results)
        failure = failure or tables
    written = [path for path in dict.fromkeys(tally) if path.is_file()]  # (a run's row is written, then folded into the table)
    print(table)
    failed = sum(1 for run in results["runs"] if run.get("failed"))
    for line in failures(results):
        print(f"ctsim: {line}", file=sys.stderr)
    if failed:
        print(f"ctsim: {failed} of {len(results['runs'])} runs failed: see 'failed' in {sanitize.name(str(out / RESULTS), 1000)}", file=sys.stderr)
    if failure is not None:
        said = failure.strerror if isinstance(failure, OSError) and failure.strerror else str(failure)
        kept = ", ".join(path.name for path in written) or "nothing"
        print(sanitize.name(f"ctsim: error: writing the results into {out}: {said} (written: {kept})", 3000), file=sys.stderr)
        return EXIT_FAILED
    print("wrote:\n" + "\n".join(f"  {sanitize.name(str(path), 1000)}" for path in written))
    return EXIT_FAILED if failed else 0


def _writing(write: Callable[[], object]) -> Exception | None:
    """Why `write` could not write its files (a full disk, a folder planted at a file's name), or None."""
    from sim.out_files import NotAFileOfItsOwn

    try:
        write()
    except (OSError, NotAFileOfItsOwn) as err:
        return err
    return None


SHOWN_FAILURES = 5
"""Failed runs said one line each on the terminal; the rest are counted (all are in results.json)."""


def failures(results: dict) -> list[str]:
    """One line per failed run (at most SHOWN_FAILURES, then how many more): the scenario, the seed,
    the file of the estimator that failed it and how (what the run loop said: its name, the step,
    the file and line)."""
    from sim.experiments.evaluation import failed_runs

    lines = [sanitize.name(f"{row['scenario']} seed {row['seed']} failed: {row['source']}: {row['error']}", 2000) for row in failed_runs(results)]
    return lines[:SHOWN_FAILURES] + ([f"... and {len(lines) - SHOWN_FAILURES} more failed"] if len(lines) > SHOWN_FAILURES else [])
