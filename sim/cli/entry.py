"""The `ctsim` command line: run, view, play, report, sweep, evaluate, umbmark, contest, worlds, check, controllers, lab.

User mistakes (bad world files, robot files, controller names or parameters, unwritable folders)
(`sim.errors.UserError`, or an OSError on a path the command line named) end in one line
`ctsim: error: ...` and exit status 2, never a traceback; a run that fails mid-way exits 1 after
everything up to then has been written, as does the user's controller or estimator failing while
it is made (`UserCodeFailed`, one line); any other exception is a bug in ctsim: its traceback, a
line asking for a report, exit 1 (EXIT_STATUSES lists every status).
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import os
import signal
import sys
import threading
import traceback
from pathlib import Path

import sim
from sim import sanitize
from sim.cli import bridge, check, contest, controllers, evaluate, lab, play, report, run, sweep, umbmark, view, worlds
from sim.cli.observers import terminate
from sim.cli.options import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_TERMINATED, EXIT_USER, Parser
from sim.cli.output import held
from sim.errors import UserError
from sim.run.ending import Terminated
from sim.views.recording.arrow import quiet_rerun
from sim.world import compiling

NO_ROOM = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)
"""Errors of a full disk, a quota or the file-size limit (`ulimit -f`): the machine's, not a bug,
whichever file of ctsim's met them."""


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="ctsim", description="A 2D simulator of c't-Bot style differential-drive robots.")
    parser.add_argument("--version", action="version", version=f"ctsim {sim.__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")
    for command in (run, view, play, report, worlds, check, bridge, sweep, evaluate, umbmark, controllers, lab, contest):  # the order of --help
        command.add_parser(commands)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `ctsim` console script; returns the exit code. What the command prints
    on stderr, its own lines and those of the libraries it uses, is escaped as ctsim's messages
    are (`sanitize.Terminal`); rerun's own log lines, which its Rust side writes past that, are
    silenced (`quiet_rerun`)."""
    quiet_rerun()
    stderr, sys.stderr = sys.stderr, sanitize.Terminal(sys.stderr)
    try:
        return _command(argv)
    finally:
        sys.stderr = stderr


def _command(argv: list[str] | None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return EXIT_USER
    previous = signal.signal(signal.SIGTERM, terminate)
    said = compiling.PROGRESS  # someone waits, at a terminal or on a log: say why the first run takes a while, and how it goes
    compiling.PROGRESS = lambda line: print(f"ctsim: {line}", file=sys.stderr, flush=True)
    try:
        return args.handler(args)
    except BrokenPipeError:  # `ctsim controllers | head`: the reader has all it wanted
        sys.stdout = None
        return 0
    except UserError as err:
        print(f"ctsim: error: {sanitize.name(str(err), 2000)}", file=sys.stderr)
        return err.exit_status
    except OSError as err:
        if not (_names_user_path(err, args) or err.errno in NO_ROOM):
            return _bug()
        where = f"{err.filename}: " if err.filename else ""  # no errno, no repr
        print(f"ctsim: error: {sanitize.name(f'{where}{err.strerror or err}', 2000)}", file=sys.stderr)
        return EXIT_USER
    except KeyboardInterrupt as stop:  # outside a run (a run keeps its results and ends normally)
        terminated = isinstance(stop, Terminated)
        print(f"ctsim: {'terminated' if terminated else 'interrupted'}", file=sys.stderr)
        return EXIT_TERMINATED if terminated else EXIT_INTERRUPTED
    except Exception:
        return _bug()
    finally:
        signal.signal(signal.SIGTERM, previous)
        compiling.PROGRESS = said
        while held:
            held.pop().close()


def leave(status: int) -> int:
    """How the process ends after `main` returned `status`: at once (`os._exit`, its output
    flushed) when Ctrl-C or SIGTERM stopped the command, since everything it wrote is closed by
    then and Python's teardown of numba, Dask, rerun and pandas keeps whoever stopped it waiting
    for seconds on a busy machine, or when a controller left a thread running, which Python would
    wait for; otherwise `status`, for a normal exit."""
    stray = any(t.is_alive() and not t.daemon for t in threading.enumerate() if t is not threading.main_thread())
    if stray or status in (EXIT_INTERRUPTED, EXIT_TERMINATED):
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):  # (a closed or replaced stream: nothing left to flush)
                stream.flush()
        os._exit(status)
    return status


def _names_user_path(err: OSError, args: argparse.Namespace) -> bool:
    """Whether the failed file is one the command line named (an argument or an option), lies
    inside one, or is a folder on the way to one: the user's to fix (exit 2), not ctsim's bug."""
    failed = [Path(os.fsdecode(name)).absolute() for name in (err.filename, err.filename2) if name not in (None, "")]
    named = []
    for value in vars(args).values():
        for item in value if isinstance(value, list) else [value]:
            if isinstance(item, str | Path) and str(item).strip():
                named.append(Path(str(item).partition(".py:")[0]).absolute())  # FILE.py:Class names FILE.py
    return any(path == given or given in path.parents or path in given.parents for path in failed for given in named)


def _bug() -> int:
    """The traceback of an exception that is no user mistake, and what to do about it: exit 1."""
    traceback.print_exc()
    print(f"ctsim: error: this is a bug in ctsim {sim.__version__}, not a mistake of yours: please report it "
          "with the command you ran and the traceback above", file=sys.stderr)
    return EXIT_FAILED
