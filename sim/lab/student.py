"""The checker's handle on a student's file: a `sim.sandbox.Sandbox` with a time budget per scenario,
and the checks that turn what comes back into numbers and commands or a `StudentError`.

Each request waits at most what is left of the scenario's budget; one that runs over ends the
student's process (a fresh one starts for the next scenario). Starting the process is not the
scenario's time, but it is the submission's: the whole submission has a wall-clock budget
(`wall`, start-ups included) after which its process is ended and nothing more of it is run, so
that code which sleeps at every start or overruns every call holds a grading slot for that long
at most, not once per scenario.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from bots.commands import Command, CurveCommand, Twist, WheelSpeeds
from sim.sandbox import Limits, Sandbox, StudentError
from sim.sandbox.wire import Opaque

COMMANDS = {"WheelSpeeds": (WheelSpeeds, 2), "Twist": (Twist, 3), "CurveCommand": (CurveCommand, 3)}
"""A command list's type name -> the command type and its number count."""


class Student:
    """A student's file, run in a sandbox of its own. `modules`: the project modules its template
    imports (all of the project it can see); `cpu`: CPU seconds for its whole life; `folder`: its
    whole folder is the submission (helper modules beside it); `degraded`: allow running without
    isolation where bubblewrap is missing; `wall`: seconds of wall-clock time for all of it, from
    now, start-ups included."""

    def __init__(self, path: str | Path, modules: tuple[str, ...] = (), cpu: float = 60.0, folder: bool = False, degraded: bool = False,
                 wall: float = math.inf):  # fmt: skip
        self.box = Sandbox(path, modules, Limits(cpu=cpu), folder, degraded)
        self.budget = math.inf
        self.wall, self.deadline = wall, time.monotonic() + wall

    @property
    def spent(self) -> bool:
        """Whether the submission's wall-clock budget is used up (nothing more of it runs)."""
        return time.monotonic() >= self.deadline

    def _over(self) -> StudentError:
        self.box.close()
        message = f"your submission used up its {self.wall:g} s of time (start-ups included): it was ended, and what was left is not run"
        return StudentError("budget", message, message)

    def take_output(self) -> str:
        """What the student's code printed since the last call (one scenario's output)."""
        return self.box.take_output()

    @property
    def alive(self) -> bool:
        """Whether the student's process runs (after a timeout or a crash it does not)."""
        return self.box.process is not None

    @property
    def degraded(self) -> bool:
        return self.box.degraded

    @property
    def output(self) -> str:
        """The start of what the student's code printed."""
        return self.box.output

    def begin(self, budget: float) -> None:
        """Start a scenario with `budget` seconds of the student's computing time."""
        self.budget = budget

    def _timed(self, ask: Callable[[float], Any]) -> Any:
        if self.spent:
            raise self._over()
        try:
            if not self.alive:
                self.box.start(min(self.box.limits.startup, self.deadline - time.monotonic()))  # a StudentError if it does not load
            started = time.perf_counter()
            try:
                return ask(min(self.budget, self.deadline - time.monotonic()))
            finally:
                self.budget -= time.perf_counter() - started
        except StudentError as err:
            if err.kind == "timeout" and self.spent:
                raise self._over() from None
            raise

    def call(self, name: str, *args: Any) -> Any:
        """`name(*args)` in the student's file; plain data back."""
        return self._timed(lambda budget: self.box.call(name, *args, timeout=budget))

    def new(self, name: str, **kwargs: Any) -> int:
        """Make `name(**kwargs)` (a class) in the student's process; returns a handle."""
        return self._timed(lambda budget: self.box.new(name, timeout=budget, **kwargs))

    def method(self, handle: int, name: str, *args: Any, attribute: str | None = None, what: str = "") -> Any:
        """`object.name(*args)` of the handle's object (its `attribute` after the call if given)."""
        return self._timed(lambda budget: self.box.method(handle, name, *args, timeout=budget, attribute=attribute, what=what))

    def feed(self, handle: int, name: str, series: list[tuple], attribute: str, name_call: Callable[[int], str]) -> list:
        """`object.name(*args)` for each of `series`, `attribute` after each, in one request."""
        return self._timed(lambda budget: self.box.feed(handle, name, series, attribute, budget, name_call))

    def step(self, handle: int, t: float, readings: Any, what: str) -> Command:
        """A controller's step(t, readings), checked into a Command."""
        return command(self._timed(lambda budget: self.box.step(handle, t, readings, budget, what)), what)

    def close(self) -> None:
        """End the student's process and all it started."""
        self.box.close()

    def __enter__(self) -> Student:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def numbers(value: Any, shape: tuple[int, ...], what: str, infinite: bool = False) -> np.ndarray:
    """A student's returned value as a float array of `shape`, or a StudentError saying what is
    wrong; NaN is always wrong, infinity unless `infinite`."""
    if isinstance(value, Opaque):
        message = f"{what} returned a {value.type_name}; expected numbers of shape {shape}"
        raise StudentError("type", message, message)
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        message = f"{what} returned {type(value).__name__} that is not numbers; expected shape {shape}"
        raise StudentError("type", message, message) from None
    if array.shape != shape:
        message = f"{what} returned shape {array.shape}; expected {shape}"
        raise StudentError("shape", message, message)
    if np.isnan(array).any() or not (infinite or np.isfinite(array).all()):
        message = f"{what} returned NaN" + ("" if infinite else " or infinity")
        bad = np.isnan(array) | (np.isinf(array) & (not infinite))
        index = tuple(int(i) for i in np.argwhere(bad)[0])
        where = f": {array.tolist()}" if array.size <= 6 else f" first at index {index} of {array.shape}, {int(bad.sum())} values in all"
        raise StudentError("nan", message + where, message)
    return array


def command(value: Any, what: str) -> Command:
    """A command list from the sandbox ([type name, numbers...]) as a Command, or a StudentError."""
    kind, rest = (value[0], value[1:]) if isinstance(value, list) and value and isinstance(value[0], str) else ("", [])
    if kind == "bad" or kind not in COMMANDS or len(rest) != COMMANDS[kind][1] or not all(isinstance(v, (int, float)) for v in rest):
        returned = rest[0] if kind == "bad" and rest and isinstance(rest[0], str) else "value of another kind"
        message = f"{what} returned a {returned[:80]}; expected WheelSpeeds, Twist or CurveCommand (bots.commands)"
        raise StudentError("type", message, message)
    if not all(math.isfinite(v) for v in rest):
        message = f"{what} returned a command with NaN or infinity"
        raise StudentError("nan", f"{message}: {kind} {rest}", message)
    return COMMANDS[kind][0](*rest)
