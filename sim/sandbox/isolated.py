"""A user's own controller and estimators in a supervised process of their own (`ctsim run
--isolate`): the sandbox of contest entries (`sim.sandbox.controller`), with the file's folder
readable and limits fit for a long run. What the code does there (ignore SIGTERM through ctypes,
stop timers, replace functions, print without end, exit) cannot reach the run: the run's process
waits for each answer at most the step time limit, then ends the child, and ends it too when the
run ends or is stopped by a signal.

Its code may import numpy, the standard library and `bots.commands` (`MODULES`); it is made and
reset in its process at the run's start; its parameters (`--param`) are not passed.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from bots.commands import Command
from bots.controller import ControllerError, ControllerStopped
from bots.odometry.user import EstimatorError, load
from bots.readings import Readings
from bots.spec import RobotSpec
from sim.errors import UserCodeFailed, UserError
from sim.sandbox.box import Limits, Sandbox, StudentError
from sim.sandbox.controller import MODULES, SandboxedController, controller_class

LIMITS = Limits(cpu=1e7, memory=4 << 30, files=256, output=1 << 40, startup=60.0)
"""A guest's limits in a run: CPU time as long as the longest run may take, 4 GiB, and output
without end (the user's own prints; the start of them is kept)."""


class IsolatedController(SandboxedController):
    """A sandboxed controller whose failures (a raise, a timeout, a crash of its process) stop its
    robot with the sandbox's message (ControllerStopped), no frame of this process named."""

    def reset(self, robot: RobotSpec) -> None:
        with _stops():
            super().reset(robot)

    def step(self, t: float, readings: Readings) -> Command:
        with _stops():
            return super().step(t, readings)


@contextmanager
def _stops() -> Iterator[None]:
    try:
        yield
    except StudentError as err:
        raise ControllerStopped(str(err)) from None


class SandboxedEstimator:
    """The run loop's estimator for a user's class in `box`: made and reset there at `reset`, and
    after each `update` its pose and covariance read there once, as plain numbers (checked by the
    run loop as any estimator's)."""

    def __init__(self, box: Sandbox, class_name: str, name: str, uncertain: bool, timeout: float):
        self.box, self.class_name, self.name, self.timeout = box, class_name, name, timeout
        self.handle: int | None = None
        self.pose: Any = None
        self._read = ["pose", "covariance"] if uncertain else ["pose"]
        if uncertain:
            self.covariance: Any = None

    def reset(self, robot: RobotSpec, pose: np.ndarray) -> None:
        with _stops():
            self.handle = self.box.new(self.class_name, timeout=self.timeout)
            self._take(self.box.method(self.handle, "reset", robot, np.asarray(pose, dtype=float), timeout=self.timeout,
                                       attribute=self._read, what=f"{self.class_name}.reset()"))  # fmt: skip

    def update(self, readings: Readings) -> None:
        with _stops():
            self._take(self.box.method(self.handle, "update", readings, timeout=self.timeout, attribute=self._read,
                                       what=f"{self.class_name}.update() at t = {readings.time:.2f} s"))  # fmt: skip

    def _take(self, values: list) -> None:
        self.pose = values[0]
        if len(values) > 1:
            self.covariance = values[1]


def estimator_class(path: Path, name: str | None) -> tuple[str, str, bool]:
    """The class of a user's estimator file (the one named, else the one with `reset` and `update`),
    its label (a literal `name = "..."` in its body, else the class's name) and whether it has a
    covariance, read from its syntax, not by running it here; a file that does not parse or has no
    such class gets its name (or 'estimator'), which fails at the run's start with the loader's message."""
    try:
        tree = ast.parse(path.read_text(encoding="utf-8", errors="replace"), str(path))
    except SyntaxError:
        return name or "estimator", name or "estimator", False
    classes = {node.name: node for node in tree.body if isinstance(node, ast.ClassDef)}
    found = [node for node in classes.values() if {"reset", "update"} <= {f.name for f in node.body if isinstance(f, ast.FunctionDef)}]
    node = classes.get(name) if name else found[0] if len(found) == 1 else None
    if node is None:
        return name or "estimator", name or "estimator", False
    label = next((a.value.value for a in node.body if isinstance(a, ast.Assign) and isinstance(a.value, ast.Constant) and isinstance(a.value.value, str)
                  and any(isinstance(t, ast.Name) and t.id == "name" for t in a.targets)), node.name)  # fmt: skip
    uncertain = any((isinstance(n, ast.FunctionDef) and n.name == "covariance") or (isinstance(n, ast.Name) and n.id == "covariance")
                    or (isinstance(n, ast.Attribute) and n.attr == "covariance") for n in ast.walk(node))  # fmt: skip
    return node.name, label, uncertain


@contextmanager
def isolated_controller(source: str, timeout: float) -> Iterator[IsolatedController]:
    """The controller of `FILE.py[:NAME]` in a process of its own, each call limited to `timeout`
    seconds; the process ended with every process it started when the block ends."""
    path, _, name = source.partition(".py")
    _refuse_missing(Path(path + ".py"), name.lstrip(":"), ControllerError)
    found, has_reset = controller_class(Path(path + ".py"))
    with _started(path + ".py", source) as box:
        yield IsolatedController(box, name.lstrip(":") or found, has_reset, timeout)


@contextmanager
def isolated_estimator(source: str, timeout: float) -> Iterator[Any]:
    """A factory of the estimator of `FILE.py[:NAME]`, each made in a process of its own (each
    call limited to `timeout` seconds), every process ended when the block ends."""
    path, _, name = source.partition(".py")
    _refuse_missing(Path(path + ".py"), name.lstrip(":"), EstimatorError)
    class_name, label, uncertain = estimator_class(Path(path + ".py"), name.lstrip(":") or None)
    with ExitStack() as stack:  # (a process per robot)

        def make() -> SandboxedEstimator:
            return SandboxedEstimator(stack.enter_context(_started(path + ".py", source)), class_name, label, uncertain, timeout)

        make.__name__ = label
        yield make


def estimator_source(source: str, timeout: float, stack: ExitStack) -> Any:
    """What a run takes for the estimator `source` with isolation: a factory making it in processes
    of its own (`isolated_estimator`, ended with `stack`) for a user's file; a shipped one, or the
    loader's one line for a missing file, as without isolation."""
    if not (source.endswith(".py") or ".py:" in source) or not Path(source.partition(".py")[0] + ".py").is_file():
        return load(source)
    return stack.enter_context(isolated_estimator(source, timeout))


def _refuse_missing(path: Path, name: str, error: type[UserError]) -> None:
    """`error` (exit 2, as without --isolate) when the file plainly defines no `name` at its top
    level, read from its syntax; a file that does not parse is left to its loading to say."""
    try:
        tree = ast.parse(path.read_text(encoding="utf-8", errors="replace"), str(path))
    except SyntaxError:
        return
    defined = {node.name for node in tree.body if isinstance(node, ast.ClassDef | ast.FunctionDef)}
    defined |= {target.id for node in tree.body if isinstance(node, ast.Assign) for target in node.targets if isinstance(target, ast.Name)}
    imported = [alias for node in tree.body if isinstance(node, ast.Import | ast.ImportFrom) for alias in node.names]
    defined |= {(alias.asname or alias.name).split(".")[0] for alias in imported}
    if name and name not in defined and not any(alias.name == "*" for alias in imported):
        raise error(f"{path}: defines no {name!r}")


@contextmanager
def _started(path: str, source: str) -> Iterator[Sandbox]:
    """A sandbox on the user's file, started (its file loaded) before the run and its clock: a
    file that does not load is one line naming it (UserCodeFailed, exit 1)."""
    with Sandbox(path, modules=MODULES, limits=LIMITS, folder=True, degraded=True) as box:
        try:
            box.start()
        except StudentError as err:
            raise UserCodeFailed(f"{source} (in its own process): {err}") from None
        yield box
