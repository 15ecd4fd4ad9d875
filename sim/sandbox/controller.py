"""A student's controller in a contest game (or a user's under `ctsim run --isolate`), run in the
sandbox that `ctsim lab grade` uses (`sim.sandbox`: bubblewrap, no pickle): its own process that
sees none of the host's files (not the contest's database or recordings, not another submission),
fed each step's readings as plain data and answering a plain command list. Whatever it does
(raise, hang, exit, flood its output, answer nonsense) fails its robot's step, and the judge gives
the game to the other bot.

The controller is the file's one class with a `step` method (else its class or function named
`controller`), found by reading the file's syntax, not by running it here. It may import numpy,
the standard library and `bots.commands`.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from bots.commands import BadCommand, Command, CurveCommand, Twist, WheelSpeeds
from bots.readings import Readings
from bots.spec import RobotSpec
from sim.errors import UserError
from sim.sandbox import Limits, Sandbox, unavailable

MODULES = ("bots.commands",)
"""What of the project a student's controller may import."""
LIMITS = Limits(cpu=120.0)
"""A guest's limits for one game: two minutes of CPU time, the sandbox's defaults otherwise."""
CALL_TIMEOUT = 10.0
"""Seconds one call (making the controller, one step) may take before it counts as hung: generous,
as several games share the machine's cores."""
COMMANDS = {"WheelSpeeds": WheelSpeeds, "Twist": Twist, "CurveCommand": CurveCommand}


def controller_class(path: Path) -> tuple[str, bool]:
    """The name of the class (or function `controller`) in a student's file that drives the robot,
    and whether it has a `reset` method, read from its syntax; a file that does not parse, or has no
    such class, gets `controller`, which fails its first step with the loader's message."""
    try:
        tree = ast.parse(path.read_text(encoding="utf-8", errors="replace"), str(path))
    except SyntaxError:
        return "controller", False
    classes = {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            methods = {f.name for f in node.body if isinstance(f, ast.FunctionDef)}
            if "step" in methods:
                classes[node.name] = "reset" in methods
    if len(classes) == 1:
        return next(iter(classes.items()))
    return "controller", classes.get("controller", False)


class SandboxedController:
    """The run loop's controller for a student's class in `box` (made at `reset`)."""

    def __init__(self, box: Sandbox, name: str, has_reset: bool, call_timeout: float = CALL_TIMEOUT):
        self.box, self.class_name, self.has_reset, self.call_timeout = box, name, has_reset, call_timeout
        self.handle: int | None = None
        self.time_left: Callable[[], float] = lambda: math.inf
        """Wall-clock seconds the entry may still spend in the game (`judge.Guarded` sets it)."""

    def _timeout(self) -> float:
        """One call's limit: `call_timeout`, or less when the game's budget has less left."""
        return min(self.call_timeout, self.time_left())

    def reset(self, robot: RobotSpec) -> None:
        self.handle = self.box.new(self.class_name, timeout=self._timeout())
        if self.has_reset:
            self.box.method(self.handle, "reset", robot, timeout=self._timeout(), what=f"{self.class_name}.reset()")

    def step(self, t: float, readings: Readings) -> Command:
        answer = self.box.step(self.handle, t, readings, timeout=self._timeout(), what=f"{self.class_name}.step() at t = {t:.2f} s")
        return command(answer, self.class_name)


def command(answer: Any, name: str) -> Command:
    """A command list from the guest ([type name, numbers...] or ["bad", type name]) as a Command,
    checked here (the guest's answer is not trusted)."""
    if isinstance(answer, list) and answer and answer[0] in COMMANDS:
        kind, *values = answer
        if all(isinstance(v, (int, float)) and math.isfinite(v) for v in values) and len(values) == len(COMMANDS[kind].__dataclass_fields__):
            return COMMANDS[kind](*values)
        raise BadCommand(f"{name}.step() returned a {kind} with numbers that are not finite")
    what = answer[1] if isinstance(answer, list) and len(answer) == 2 and isinstance(answer[1], str) else type(answer).__name__
    raise BadCommand(f"{name}.step() returned a {what}; expected WheelSpeeds, Twist or CurveCommand (bots.commands)")


def check_available() -> None:
    """Refuse student submissions (a UserError saying why) where their code cannot be isolated here."""
    reason = unavailable()
    if reason is not None:
        raise UserError(f"{reason}: student submissions run only in the sandbox (the machine needs bubblewrap, see the README)")


@contextmanager
def sandboxed_controller(path: Path) -> Iterator[SandboxedController]:
    """The controller of the student's file at `path` in a sandbox of its own, ended with every
    process it started when the block ends. Its file loads at the first `reset`; a file that does
    not load fails there (and `Guarded` makes that its first step's failure)."""
    name, has_reset = controller_class(path)
    box = Sandbox(path, modules=MODULES, limits=LIMITS)
    try:
        yield SandboxedController(box, name, has_reset)
    finally:
        box.close()
