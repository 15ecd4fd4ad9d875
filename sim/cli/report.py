"""`ctsim report`: the figures and report.html of a run folder."""

from __future__ import annotations

import argparse
from pathlib import Path

from sim import sanitize
from sim.analysis.run_folder import SUMMARY, RunFolder
from sim.cli.options import UsageError


def add_parser(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    """The `report` command's options."""
    report = commands.add_parser("report", help="draw the PNG figures and report.html of a run folder",
                                 description="Draw trajectories.png, errors.png and report.html (one self-contained page: table, figures, facts) in a folder written by `ctsim run`.")
    report.add_argument("run_dir", type=Path, metavar="RUN_DIR")
    report.set_defaults(handler=cmd_report)


def cmd_report(args: argparse.Namespace) -> int:
    from sim.views.figures import report_run_dir
    from sim.views.recording.arrow import keep_pandas_out_of_arrow

    if not RunFolder(args.run_dir).summary.is_file():
        raise UsageError(f"{args.run_dir}: not a run folder (no {SUMMARY})")
    from sim.web.report import write_run_report

    keep_pandas_out_of_arrow()  # (reading a trajectory's numbers would import pandas, some 0.7 s, for nothing: no user code runs here)
    for path in [*report_run_dir(args.run_dir), write_run_report(args.run_dir)]:
        print(sanitize.name(str(path), 1000))
    return 0
