"""Ctrl-C and SIGTERM told apart from a KeyboardInterrupt the user's code raises itself.

A signal's handler raises KeyboardInterrupt (or `sim.run.ending.Terminated`) wherever the program
is, so the exception alone cannot say whether the user pressed Ctrl-C or a controller, estimator
or constructor raised it: the first stops the command (exit 130 or 143, what finished kept), the
second is that code's error like any other exception it raises (exit 1, naming its file and line).
While `Counting`, the Python handlers of SIGINT and SIGTERM count each signal before they act: a
KeyboardInterrupt with none counted since is the code's own. Standard library only: a leaf any
layer may use.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable
from typing import Any

_received = 0
"""Signals the counting handlers took in this process so far."""
_STOPS = (signal.SIGINT, signal.SIGTERM)


class Counting:
    """Context: the Python handlers of SIGINT and SIGTERM in place count every signal, then act as
    they did; `by_signal(err)` tells a KeyboardInterrupt a signal explains from one the code raised. In the main thread
    only (no other runs a signal handler: there every KeyboardInterrupt is raised by code); a handler
    that is no Python function (the default, ignored) raises nothing and is left as it is. Nests."""

    def __init__(self) -> None:
        self.since = _received
        self.previous: dict[int, Any] = {}

    def __enter__(self) -> Counting:
        self.since = _received
        if threading.current_thread() is threading.main_thread():
            for number in _STOPS:
                handler = signal.getsignal(number)
                if callable(handler):
                    self.previous[number] = signal.signal(number, _counted(handler))
        return self

    def __exit__(self, *exc: object) -> None:
        for number, handler in self.previous.items():
            signal.signal(number, handler)
        self.previous = {}

    def by_signal(self, err: BaseException) -> bool:
        """Whether `err` is a KeyboardInterrupt that a signal since entering explains (Ctrl-C,
        SIGTERM): the command stops; any other exception is the code's that raised it."""
        return isinstance(err, KeyboardInterrupt) and _received != self.since


def _counted(handler: Callable[[int, Any], Any]) -> Callable[[int, Any], Any]:
    def counting(signum: int, frame: Any) -> Any:
        global _received
        _received += 1
        return handler(signum, frame)

    return counting
