"""The `ctsim` console script. Loading ctsim takes seconds (numpy, numba, pymunk, rerun): Ctrl-C or
SIGTERM meanwhile ends with the documented status (`sim.cli.options.EXIT_STATUSES`) and one line, not an
import's traceback; from then on `sim.cli.entry.main` handles them."""

from __future__ import annotations

import signal
import sys

STATUS = {signal.SIGINT: 130, signal.SIGTERM: 143}
"""Exit status by signal while loading: the same as `sim.cli.options.EXIT_INTERRUPTED` and `EXIT_TERMINATED`."""


def _leave(signum: int, frame: object) -> None:
    print(f"ctsim: {'interrupted' if signum == signal.SIGINT else 'terminated'} while starting", file=sys.stderr)
    raise SystemExit(STATUS[signum])


def main() -> int:
    """Load the command line with signals ending the process cleanly, then run it."""
    previous = {number: signal.signal(number, _leave) for number in STATUS}
    from sim.cli.entry import leave
    from sim.cli.entry import main as command_line

    for number, handler in previous.items():
        signal.signal(number, handler)
    return leave(command_line())
