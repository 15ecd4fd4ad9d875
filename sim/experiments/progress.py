"""How far long work has got, told as it goes: a tqdm bar on a terminal, and elsewhere (a log, a
job scheduler's output file) a line every few seconds with the count done, the count left, the
rate and the time left; a resumed job says first how much was done before.

    progress = Progress(200, done=120, unit="run", what="sweep")   # "ctsim: sweep: resuming, ..."
    progress.update()                                                # after each run
    progress.close()
"""

from __future__ import annotations

import sys
import threading
import time
from collections.abc import Callable
from typing import Any, TextIO

INTERVAL_S = 5.0
"""Seconds between two progress lines off a terminal (a line comes when work finishes after that)."""


def duration(seconds: float) -> str:
    """Seconds as people read a wait: '45 s', '12 min', '3.5 h'."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 90 * 60:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


class Progress:
    """`total` pieces of work (`unit`, e.g. "run"), `done` of them finished before this start.
    On a terminal (`stream.isatty()`) a tqdm bar, unless not `bar` (work that prints a line per
    piece); elsewhere a line at the start and then at most one every `interval` seconds, when a
    piece finishes. `clock`: seconds (for tests)."""

    def __init__(self, total: int, done: int = 0, unit: str = "run", what: str = "", stream: TextIO | None = None,
                 interval: float = INTERVAL_S, clock: Callable[[], float] = time.monotonic, bar: bool = True):  # fmt: skip
        self.total, self.done, self.unit, self.interval, self.clock = total, done, unit, interval, clock
        self.stream = sys.stderr if stream is None else stream
        self.prefix = f"ctsim: {what}: " if what else "ctsim: "
        self.started, self.before = clock(), done
        self.last = self.started
        self.lock = threading.Lock()  # (checks finishing in several threads at once, as `lab grade`'s)
        self.bar = self._bar() if bar and _isatty(self.stream) else None
        if done:
            self._say(f"resuming: {done} of {total} {self._plural(total)} already done, {total - done} to go")
        elif self.bar is None:
            self._say(f"{total} {self._plural(total)} to go")

    def _bar(self) -> Any:
        from tqdm import tqdm

        class Bar(tqdm):
            monitor_interval = 0  # no monitor thread: local workers are forked from this process when it runs one thread

        return Bar(total=self.total, initial=self.done, unit=self.unit, file=self.stream, smoothing=0.1, dynamic_ncols=True)

    def update(self, n: int = 1) -> None:
        """`n` more pieces finished."""
        with self.lock:
            self.done += n
            if self.bar is not None:
                self.bar.update(n)
                return
            now = self.clock()
            if now - self.last >= self.interval or self.done == self.total:
                self.last = now
                self._say(self.line(now))

    def line(self, now: float) -> str:
        """'120/200 runs done, 80 left, 2.3 runs/s, about 35 s left' (rate of this start's work)."""
        left = self.total - self.done
        text = f"{self.done}/{self.total} {self._plural(self.total)} done, {left} left"
        elapsed, finished = now - self.started, self.done - self.before
        if finished and elapsed > 0:
            rate = finished / elapsed
            shown = f"{rate:.2g}" if rate < 10 else f"{rate:.0f}"
            text += f", {shown} {self.unit}s/s" + (f", about {duration(left / rate)} left" if left else f", in {duration(elapsed)}")
        return text

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()

    def _say(self, text: str) -> None:
        print(self.prefix + text, file=self.stream, flush=True)

    def _plural(self, count: int) -> str:
        return self.unit if count == 1 else f"{self.unit}s"


def _isatty(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # a stand-in without isatty, or a closed stream
        return False
