"""Running a student's file in a separate process, with a time budget per scenario.

`Student` is the checker's handle on that process: each request waits at most what is left of the
scenario's budget; a request that runs over kills the process (a fresh one starts for the next
scenario). Whatever the student's code does (raise, hang, exit, return nonsense, import the
world), the checker gets a `StudentError` with a clear message, never a crash of its own.
"""

from __future__ import annotations

import math
import multiprocessing
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bots.commands import Command, CurveCommand, Twist, WheelSpeeds
from sim.lab import worker

STARTUP_LIMIT = 20.0
"""Seconds for the process to start (Python, numpy) and load the file, beyond the budget: the
machine may be busy with other gradings."""


@dataclass
class StudentError(Exception):
    """The student's code failed. `kind`: load, raised, timeout, crash, forbidden, type, shape,
    nan. `detail` may name values of the scenario; `public` never does (for hidden scenarios)."""

    kind: str
    detail: str
    public: str
    value_error: bool = False
    exception: str = ""

    def __str__(self) -> str:
        return self.detail


PRELOAD = ["sim.lab.worker", "bots.commands", "sim.world.readings"]
"""What the fork server imports once, so that each student's process starts in milliseconds
instead of starting Python and numpy again (a second or two on a busy machine)."""


def _context() -> multiprocessing.context.BaseContext:
    """Student processes fork from a server of this process that has the worker's imports loaded
    (each still a fresh process of its own); spawn where fork servers do not exist (Windows)."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return multiprocessing.get_context("spawn")
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(PRELOAD)
    return context


def _raised(info: dict[str, Any], what: str) -> StudentError:
    where = f" at line {info['line']}" if info["line"] else ""
    if info["forbidden"]:
        message = f"{what}: {info['message']}{where}"
        return StudentError("forbidden", message, message)
    detail = f"{what} raised {info['type']}{where}: {info['message']}" if info["message"] else f"{what} raised {info['type']}{where}"
    return StudentError("raised", detail, f"{what} raised {info['type']}{where}", info["value_error"], info["type"])


class Student:
    """A student's file, loaded in its own process. `forbidden`: module prefixes the exercise
    refuses besides the ground-truth ones."""

    def __init__(self, path: str | Path, forbidden: tuple[str, ...] = ()):
        self.path = Path(path).resolve()
        self.forbidden = tuple(forbidden)
        self.process: Any = None
        self.conn: Any = None
        self.budget = math.inf
        self._handles = 0

    def begin(self, budget: float) -> None:
        """Start a scenario with `budget` seconds of the student's computing time."""
        self.budget = budget

    def _start(self) -> None:
        context = _context()
        self.conn, child = context.Pipe()
        self.process = context.Process(target=worker.serve, args=(child, str(self.path), self.forbidden), daemon=True)
        self.process.start()
        child.close()
        budget = self.budget
        status, info = self._receive(STARTUP_LIMIT + budget, "loading your file")
        self.budget = budget  # starting Python is not the student's time
        if status == "error":
            self.close()
            error = _raised(info, "loading your file")
            kind = "forbidden" if info["forbidden"] else "load"
            raise StudentError(kind, error.detail, error.public)

    def _receive(self, limit: float, what: str) -> tuple[str, Any]:
        started = time.perf_counter()
        ready = self.conn.poll(max(limit, 0.0))
        self.budget -= time.perf_counter() - started
        if not ready:
            self.close()
            message = f"{what} took longer than the time limit (an endless loop?)"
            raise StudentError("timeout", message, message)
        try:
            return self.conn.recv()
        except (EOFError, OSError):
            code = self.process.exitcode if self.process is not None else None
            self.close()
            message = f"your code ended the checking process while {what} (exit code {code}: sys.exit, os._exit or a crash)"
            raise StudentError("crash", message, message) from None

    def request(self, op: str, args: tuple, what: str) -> Any:
        """Send one request and wait for its answer within the budget; `what` names it in messages."""
        if self.process is None:
            self._start()
        try:
            self.conn.send((op, args))
        except (OSError, ValueError):
            self.close()
            raise StudentError("crash", f"the checking process is gone before {what}", f"the checking process is gone before {what}") from None
        status, value = self._receive(self.budget, what)
        if status == "error":
            raise _raised(value, what)
        return value

    def call(self, name: str, *args: Any) -> Any:
        """`name(*args)` in the student's file; plain data back."""
        return self.request("call", (name, args), f"{name}()")

    def new(self, name: str, **kwargs: Any) -> int:
        """Make `name(**kwargs)` (a class) in the student's process; returns a handle."""
        self._handles += 1
        self.request("new", (self._handles, name, kwargs), f"{name}()")
        return self._handles

    def close(self) -> None:
        """End the process (killed if it does not stop at once)."""
        if self.process is not None:
            if self.conn is not None:
                self.conn.close()
            self.process.kill()
            self.process.join(timeout=5)
        self.process = self.conn = None

    def __enter__(self) -> Student:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def numbers(value: Any, shape: tuple[int, ...], what: str, infinite: bool = False) -> np.ndarray:
    """A student's returned value as a float array of `shape`, or a StudentError saying what is
    wrong; NaN is always wrong, infinity unless `infinite`."""
    if isinstance(value, dict) and "__type__" in value:
        message = f"{what} returned a {value['__type__']}; expected numbers of shape {shape}"
        raise StudentError("type", message, message)
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        message = f"{what} returned {type(value).__name__} that is not numbers; expected shape {shape}"
        raise StudentError("type", message, message) from None
    if array.shape != shape:
        message = f"{what} returned shape {array.shape}; expected {shape}"
        raise StudentError("shape", message, message)
    if np.isnan(array).any() or not (infinite or np.isfinite(array).all()):
        message = f"{what} returned NaN" + ("" if infinite else " or infinity")
        raise StudentError("nan", f"{message}: {array.tolist()}", message)
    return array


def command(value: tuple, what: str) -> Command:
    """A controller's command tuple from the worker as a Command, or a StudentError."""
    kind, *rest = value
    if kind == "bad":
        message = f"{what} returned a {rest[0]}; expected WheelSpeeds, Twist or CurveCommand (bots.commands)"
        raise StudentError("type", message, message)
    if not all(math.isfinite(v) for v in rest):
        message = f"{what} returned a command with NaN or infinity"
        raise StudentError("nan", f"{message}: {kind} {rest}", message)
    return {"wheels": WheelSpeeds, "twist": Twist, "curve": CurveCommand}[kind](*rest)
