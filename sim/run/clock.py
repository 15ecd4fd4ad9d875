"""A wall-clock time limit on each controller step, kept by SIGALRM."""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from sim.errors import UserCodeFailed
from sim.run.ending import RunError, stopped_by

MAX_STEP_TIMEOUT = 86_400.0
"""Longest wall-clock time limit on a controller step (s): a day; the operating system's timer
holds no more than about 10^8 s."""
MIN_STEP_TIMEOUT = 0.05
"""Shortest (s): its timer ticks every quarter of it, and a tick runs a Python handler; at 1e-9 s
the ticks came faster than the handler ran, and the run never ended."""
STEP_TIMEOUT = 5.0
"""Seconds (wall clock) a call of the user's code may take unless told otherwise: the default of
`ctsim run --step-timeout`, of `ctsim evaluate --step-timeout` and of `evaluate()`."""


class StepTimeout(BaseException):
    """A controller step ran past its time limit (a BaseException, so that a controller's own
    `except Exception` does not swallow it)."""


_END_PROCESS = os._exit
"""os._exit as it was when ctsim started (a run's guard replaces it meanwhile: `sim.guards`)."""
OVERRUN_STATUS = 124
"""Exit status of a process that an overrun ended (`StepClock.ends_process`), as `timeout`'s."""


class StepClock:
    """A time limit on each controller step, kept by SIGALRM: a timer ticks every quarter of the
    limit and raises StepTimeout inside a controller that the last four ticks found in the same
    step (so a step ends between 1 and 1.25 limits). Only in the main thread of a POSIX process
    (signals go there); elsewhere steps are not timed, unless `ends_process`: then a thread ticks
    and ends the process at an overrun (no exception can be raised into a call blocked in
    another thread). `busy` is the number of the call of user code in progress (a controller's
    step or an estimator's update: `begin`; 0: none)."""

    active: StepClock | None = None
    """The clock of the run going on in this process, if any."""
    ends_process = False
    """Whether an overrun off the main thread ends this process: set in a Dask worker
    (`sim.experiments.engines`), whose runs go in threads; a worker that ends is replaced, its run
    tried again and then reported lost, rather than holding the sweep for ever."""

    def __init__(self, limit: float | None):
        if limit is not None and not (isinstance(limit, (int, float)) and MIN_STEP_TIMEOUT <= limit <= MAX_STEP_TIMEOUT):
            raise RunError(f"the step time limit must be at least {MIN_STEP_TIMEOUT:g} s and at most {MAX_STEP_TIMEOUT:,.0f} s (a day), got {limit!r}")
        self.limit = limit
        self.busy = 0
        self.calls = 0
        self.stopping: int | None = None
        """A stopping signal noted outside user code (`stop_user_code`): the next call raises it as it begins."""
        self._seen, self._ticks, self._previous = 0, 0, None
        self.armed = bool(limit) and hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()
        self.watched = bool(limit) and not self.armed and StepClock.ends_process
        self._stopped = threading.Event()

    def __enter__(self) -> StepClock:
        if self.armed:
            self._previous = signal.signal(signal.SIGALRM, self._tick)
            signal.setitimer(signal.ITIMER_REAL, self.limit / 4, self.limit / 4)
            StepClock.active = self
        elif self.watched:
            threading.Thread(target=self._watch, name="ctsim step clock", daemon=True).start()
        return self

    def __exit__(self, *exc: object) -> None:
        if self.armed:
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.signal(signal.SIGALRM, self._previous)
            StepClock.active = None
        self._stopped.set()

    def _watch(self) -> None:
        """The ticks of a clock off the main thread (`ends_process`): an overrun ends the process."""
        while not self._stopped.wait(self.limit / 4):
            if self.busy and self.busy == self._seen:
                self._ticks += 1
                if self._ticks >= 4:
                    _END_PROCESS(OVERRUN_STATUS)
            else:
                self._seen, self._ticks = self.busy, 0

    def begin(self) -> None:
        """A call of user code (a controller's step, an estimator's update) starts: timed from now."""
        self.calls += 1
        self.busy = self.calls
        if self.stopping is not None:  # (after `busy` is set: a signal from here on raises in its handler)
            raise stopped_by(self.stopping)

    def _tick(self, signum: int, frame: object) -> None:
        if self.busy and self.busy == self._seen:
            self._ticks += 1
            if self._ticks >= 4:
                raise StepTimeout
        else:
            self._seen, self._ticks = self.busy, 0


def stop_user_code(signum: int) -> None:
    """For a signal handler: stop the user's code of the run in this process at once where a call
    of it (a controller's step, an estimator's update) is going on (no ctsim lock is held there;
    raises `stopped_by(signum)`), else as the next call begins, before any of it runs: a call that
    then blocks (a controller deaf to the signal, waiting on a pipe) must not hold the run until
    its step time limit. Checking for a call and beginning one cannot interleave so that the
    signal is missed: `begin` looks after marking the call."""
    clock = StepClock.active
    if clock is None:
        return
    clock.stopping = signum
    if clock.busy:
        raise stopped_by(signum)


MAKING_STEPS = 12
"""Step time limits the user's code may take to load and be made (`made_in_time`): a file that
imports a large library takes seconds (a minute under the default limit)."""


@contextmanager
def made_in_time(limit: float | None) -> Iterator[None]:
    """The user's code run before a run (loading its files, its constructors) under MAKING_STEPS
    times the limit of each of its steps (`StepClock`; None: none): UserCodeFailed, one line naming
    the line of the user's code it was in, once it takes longer, rather than a command that never
    ends."""
    from bots.controller import where

    StepClock(limit)  # (a limit out of bounds refused as such)
    allowed = None if limit is None else min(MAKING_STEPS * limit, MAX_STEP_TIMEOUT)
    clock = StepClock(allowed)
    with clock:
        clock.begin()
        try:
            yield
        except StepTimeout as err:
            raise UserCodeFailed(f"loading or making the controllers and estimators took longer than {allowed:g} s ({MAKING_STEPS} step time limits){where(err)}") from None
        finally:
            clock.busy = 0
