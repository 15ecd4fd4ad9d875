"""Observers the commands add to a run: Ctrl-C and SIGTERM by phase, and a progress bar."""

from __future__ import annotations

import signal
import sys
from typing import Any

from sim.cli.options import EXIT_INTERRUPTED, EXIT_TERMINATED
from sim.run.clock import stop_user_code
from sim.run.ending import Terminated, stopped_by


def terminate(signum: int, frame: Any) -> None:
    raise Terminated


class StopOnSignal:
    """Run observer and context for Ctrl-C and SIGTERM, by phase (`phase`):

    - "setup" (loading, building the world): a signal stops at once; nothing is written yet.
    - "run" (from the run's start): a signal asks the run to stop at the next step boundary. A
      signal raised wherever the process happens to be (inside rerun's stream, a compiled kernel, a
      socket call) can leave a lock held, and the run would hang instead of writing what it has.
      Inside a call of the user's code (a controller's step, an estimator's update) it stops at
      once, and before the next such call if it came between two (`sim.run.clock.stop_user_code`):
      a controller that blocks must not make the run deaf. A second signal stops at once.
    - "write" (summary and trajectories): signals are only noted, so those files are whole.
    - "draw" (figures): a signal stops at once; the figures can be drawn later (`ctsim report`).
    """

    def __init__(self) -> None:
        self.received: int | None = None
        self.phase = "setup"
        self._previous: dict[int, Any] = {}
        self.starting = _Starting(self)
        """An observer to put first: the run has started (its on_start) when it is called."""

    def __enter__(self) -> StopOnSignal:
        self._previous = {s: signal.signal(s, self._handle) for s in (signal.SIGINT, signal.SIGTERM)}
        return self

    def __exit__(self, *exc: Any) -> None:
        for number, handler in self._previous.items():
            signal.signal(number, handler)

    def _handle(self, signum: int, frame: Any) -> None:
        first = self.received is None
        self.received = self.received or signum
        if self.phase in ("setup", "draw") or (self.phase == "run" and not first):
            raise stopped_by(signum)
        if self.phase == "run":
            stop_user_code(signum)

    def status(self) -> int | None:
        """The exit status a signal received so far asks for (None: none received)."""
        return None if self.received is None else EXIT_TERMINATED if self.received == signal.SIGTERM else EXIT_INTERRUPTED

    def on_sample(self, world: Any, logs: Any) -> None:
        if self.received is not None:
            raise stopped_by(self.received)

    def on_end(self, result: Any) -> None:
        self.phase = "write"


class _Starting:
    """The observer that moves a StopOnSignal from "setup" to "run"."""

    def __init__(self, stop: StopOnSignal):
        self.stop = stop

    def on_start(self, world: Any, logs: Any) -> None:
        self.stop.phase = "run"


class Progress:
    """tqdm progress bar on stderr over simulated time; shown only on a terminal and only when
    the run takes more than a second."""

    def __init__(self, duration: float, dt: float, every: int = 100):
        self.duration, self.dt, self.every = duration, dt, every
        self.bar: Any = None
        self._count = 0

    def on_start(self, world, logs) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=round(self.duration, 6), unit="s sim", delay=1.0, disable=not sys.stderr.isatty(), leave=False, file=sys.stderr,
                        bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s sim [{elapsed}<{remaining}]")

    def on_sample(self, world, logs) -> None:
        self._count += 1
        if self._count % self.every == 0:
            self.bar.update(world.time - self.bar.n)

    def on_end(self, result) -> None:
        if self.bar is not None:  # (None when the run stopped before it started)
            self.bar.close()
