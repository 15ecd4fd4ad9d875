"""`ctsim sweep`: many runs from a TOML spec, resumable, and `sweep report`."""

from __future__ import annotations

import argparse
from pathlib import Path

from sim import sanitize
from sim.cli.options import UsageError, add_engine_options, engine_of
from sim.run.ending import Ending


def add_parser(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    sweep = commands.add_parser(
        "sweep",
        help="run many runs from a TOML spec (grid or random), resumable; `sweep report DIR` draws its figures",
        description="Run every run a sweep spec plans (see README, 'Sweeps') on local processes (default, all cores) or Dask, "
        "one Parquet row per run in DIR/results.parquet, kept as runs finish: run it again to finish an interrupted sweep. "
        "`ctsim sweep report DIR` draws the figures of a sweep folder.",
    )
    sweep.add_argument("spec", metavar="SPEC.toml|report", help="the sweep spec, or `report` followed by a sweep folder")
    sweep.add_argument("folder", nargs="?", type=Path, metavar="DIR", help="(with report) the sweep folder")
    sweep.add_argument("--out", type=Path, metavar="DIR", help="sweep folder (default: runs/sweep-<spec name>)")
    add_engine_options(sweep)
    sweep.add_argument("--by", action="append", metavar="SETTING",
                       help="group the summary and figures by this setting, repeatable (default: every swept one but seed); the others are pooled, and each table and figure says so")
    sweep.set_defaults(handler=cmd_sweep)


def cmd_sweep(args: argparse.Namespace) -> int:
    from sim.experiments import load_results, load_sweep, sweep
    from sim.experiments.report import grouping, pooled_note, summary_table, terminal_table

    def show(table) -> None:  # noqa: ANN001 (a DataFrame)
        by, pooled = grouping(table, args.by)
        print(f"per {', '.join(by) or 'sweep'}; {pooled_note(table, pooled)}:")
        print(terminal_table(summary_table(table, by)))

    if args.spec == "report":
        from sim.web.report import write_sweep_report

        if args.folder is None or not args.folder.is_dir():
            raise UsageError(f"sweep report needs a sweep folder, got {args.folder}")
        paths = write_sweep_report(args.folder, by=args.by)
        show(load_results(args.folder))
        for path in paths:
            print(sanitize.name(str(path), 1000))
        return 0
    if args.folder is not None:
        raise UsageError(f"unexpected argument {str(args.folder)!r} (the folder goes in --out)")
    spec = load_sweep(args.spec)
    out = args.out or Path("runs") / f"sweep-{Path(args.spec).stem}"
    runner = engine_of(args)
    try:
        table = sweep(spec, out, runner)
    finally:
        runner.close()
    failed = int((table["reason"] == Ending.ERROR).sum())
    show(table)
    print(f"{len(table)} runs, {failed} failed (see the error column); table: {sanitize.name(str(out / 'results.parquet'), 1000)}")
    return 0
