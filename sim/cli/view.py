"""`ctsim view`: a run's recording served with rerun's web viewer."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sim.cli.options import add_web_options
from sim.run.ending import Terminated


def serve_until_interrupted(web, what: str = "") -> None:
    """Serve until Ctrl-C, which is then the normal end (SIGTERM ends as everywhere else)."""

    print(f"ctsim: serving {what}{web.url} until Ctrl-C", flush=True)
    try:
        web.wait()
    except KeyboardInterrupt as stop:
        if isinstance(stop, Terminated):
            raise
    print("ctsim: stopped serving", file=sys.stderr)


def add_parser(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    """The `view` command's options."""
    view = commands.add_parser(
        "view",
        help="serve a run's recording and rerun's web viewer to a browser",
        description="Serve a run's recording (RUN_DIR/run.rrd or a .rrd file) with rerun's web viewer, laid out as in the "
        "native viewer, and print the page's address; serves until Ctrl-C. Nothing to install but ctsim and a browser.",
    )
    view.add_argument("recording", type=Path, metavar="RUN_DIR|RUN.rrd")
    add_web_options(view)
    view.set_defaults(handler=cmd_view)


def cmd_view(args: argparse.Namespace) -> int:
    from sim.web.serve import DEFAULT_HOST, DEFAULT_PORT, WebViewer, recording_of

    recording = recording_of(args.recording)
    with WebViewer(recording, args.host or DEFAULT_HOST, DEFAULT_PORT if args.port is None else args.port) as web:
        serve_until_interrupted(web, f"{recording} at ")
    return 0
