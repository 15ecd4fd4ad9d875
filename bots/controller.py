"""The controller interface, the registry of named controllers, and loading a student's file.

A controller is any object with `step(t, readings) -> Command` (and optionally `reset(robot)`,
called once before the first step with the robot's `RobotSpec`). Behaviours that can end also
carry a `status`: RUNNING until they finish with SUCCESS or FAILURE, so a behaviour can run
another and learn how it went. A plain function `f(t, readings) -> Command` is a controller too.
Nothing here assumes the controller is Python in this process: the run loop only calls `step`.
"""

from __future__ import annotations

import enum
import importlib.util
import inspect
import os
import sys
import sysconfig
import traceback
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol, runtime_checkable

from bots.commands import Command
from bots.readings import Readings
from bots.schema import parse_number
from bots.spec import RobotSpec
from sim.errors import UserCodeFailed, UserError
from sim.interrupts import Counting


class Status(enum.Enum):
    """How a behaviour is doing."""

    RUNNING = "running"
    SUCCESS = "success"
    FAILURE = "failure"


@runtime_checkable
class Controller(Protocol):
    """What runs on a robot: readings in, command out, once per step."""

    def step(self, t: float, readings: Readings) -> Command: ...


class ControllerStopped(RuntimeError):
    """Raised by a controller (or estimator) that cannot go on for a reason outside its own code
    in this process (a firmware peer that hung or vanished, code in a process of its own that
    failed): the run ends with this message, naming the robot and step."""


class ControllerError(UserError):
    """A user mistake in naming, configuring or loading a controller (message for the CLI)."""


class FunctionController:
    """Wraps a plain function `f(t, readings) -> Command` as a controller."""

    def __init__(self, function: Callable[[float, Readings], Command]):
        self.function = function
        self.name = getattr(function, "__name__", "function")
        self.status = Status.RUNNING

    def step(self, t: float, readings: Readings) -> Command:
        return self.function(t, readings)


REGISTRY: dict[str, Callable[..., Controller]] = {}


def register(name: str) -> Callable:
    """Class decorator: make a controller available by `name` on the command line."""

    def add(factory: Callable[..., Controller]) -> Callable[..., Controller]:
        REGISTRY[name] = factory
        return factory

    return add


def _convert(text: str, annotation: Any, default: Any) -> Any:
    """A command-line value as the type the factory's parameter expects: its annotation (a type
    or, under `from __future__ import annotations`, its name), else its default's type."""
    named = {"float": float, "int": int, "bool": bool, "str": str}
    kind = named.get(annotation, annotation) if annotation is not inspect.Parameter.empty else None
    if not isinstance(kind, type):
        kind = type(default) if default is not inspect.Parameter.empty and default is not None else str
    if kind is bool:
        if text.lower() in ("1", "true", "yes", "on"):
            return True
        if text.lower() in ("0", "false", "no", "off"):
            return False
        raise ValueError(f"expected true or false, got {text!r}")
    if kind in (int, float):
        return parse_number(text, kind)
    return text


def parameters(factory: Callable[..., Controller]) -> dict[str, inspect.Parameter]:
    """The keyword parameters a controller factory takes (what `--param KEY=VALUE` may set)."""
    return {
        name: p
        for name, p in inspect.signature(factory).parameters.items()
        if p.kind in (p.POSITIONAL_OR_KEYWORD, p.KEYWORD_ONLY)
    }


def build(factory: Callable[..., Controller], params: dict[str, str], label: str) -> Controller:
    """Call a factory with string parameters converted to its annotated types."""
    accepted = parameters(factory)
    kwargs = {}
    for key, text in params.items():
        if key not in accepted:
            known = ", ".join(accepted) or "none"
            raise ControllerError(f"controller {label!r} has no parameter {key!r} (parameters: {known})")
        p = accepted[key]
        try:
            kwargs[key] = _convert(text, p.annotation, p.default)
        except ValueError as err:
            raise ControllerError(f"controller {label!r}, parameter {key}: {err}") from None
    counted = Counting()  # (a KeyboardInterrupt the code raises is its error; Ctrl-C stops)
    try:
        with counted:
            made = factory(**kwargs)
    except (TypeError, ValueError) as err:  # a parameter it cannot take
        raise ControllerError(f"controller {label!r}: {err}") from None
    except (Exception, SystemExit, KeyboardInterrupt) as err:  # the user's code failing (or leaving): theirs, not a way out of ctsim
        if counted.by_signal(err):
            raise
        raise UserCodeFailed(f"controller {label!r}: making it {did(err)}{where(err)}") from None
    try:
        return made if hasattr(made, "step") else FunctionController(made)
    except (Exception, SystemExit) as err:  # (a `step` property that raises)
        raise UserCodeFailed(f"controller {label!r}: asking it for its step {did(err)}{where(err)}") from None


def load_file(path: str | Path, name: str | None = None) -> Callable[..., Controller]:
    """The controller defined in a student's Python file: the class or function called `name`,
    else the single class with a `step` method, else a function called `controller`."""
    path = Path(path)
    module = user_module(path, "controller", ControllerError)
    if name:
        if not hasattr(module, name):
            raise ControllerError(f"{path}: defines no {name!r}")
        found = getattr(module, name)
    else:
        classes = [v for v in vars(module).values() if inspect.isclass(v) and v.__module__ == module.__name__ and hasattr(v, "step")]
        if len(classes) == 1:
            found = classes[0]
        elif callable(getattr(module, "controller", None)):
            found = module.controller
        else:
            raise ControllerError(
                f"{path}: expected one class with a step(t, readings) method or a function named 'controller'; "
                "name the one to use with FILE:NAME"
            )
    if inspect.isclass(found) or not _takes_readings(found):
        return found
    return lambda: FunctionController(found)


MAX_SOURCE_BYTES = 16 * 2**20
"""Largest controller or estimator file loaded: Python holds a file's text and its compiled code in
memory at once (a 200 MB file of comments took 700 MB and 20 s)."""


def user_module(path: Path, kind: str, error: type[UserError]) -> types.ModuleType:
    """A user's Python file run as a module (a controller's, an estimator's); `error` names the
    file and line where it failed to load, with no traceback of ours."""
    if not path.is_file():
        raise error(f"{path}: not a regular file (a pipe, device or folder); give the {kind}'s .py file" if path.exists() else f"{path}: no such {kind} file")
    if path.stat().st_size > MAX_SOURCE_BYTES:
        raise error(f"{path}: {path.stat().st_size:,} bytes, more than {'an' if kind[0] in 'aeiou' else 'a'} {kind}'s file may have ({MAX_SOURCE_BYTES:,}); keep data in files it reads")
    spec = importlib.util.spec_from_file_location(f"ctsim_user_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    counted = Counting()
    try:
        with counted:
            spec.loader.exec_module(module)
    except (Exception, SystemExit, KeyboardInterrupt) as err:  # the user's code (sys.exit too): report where it failed, not our traceback
        if counted.by_signal(err):
            raise
        line = _user_line(err, path)
        raise error(f"{path}:{line}: {type(err).__name__}: {err}") from None
    return module


def did(err: BaseException) -> str:
    """What user code did that ended it, for a line: 'called sys.exit(3)' or 'raised T: message'."""
    if isinstance(err, SystemExit):
        return f"called {getattr(err, 'via', 'sys.exit')}({err.code!r})"
    if isinstance(err, ControllerStopped):
        return f"stopped: {err}"
    return f"raised {type(err).__name__}: {err}" if str(err) else f"raised {type(err).__name__}"


_MACHINERY = (str(Path(__file__).resolve().parents[1] / "sim") + os.sep, str(Path(__file__).resolve()), str(Path(__file__).resolve().parent / "odometry" / "user.py"),
              *(sysconfig.get_paths()[key] + os.sep for key in ("stdlib", "platstdlib", "purelib", "platlib")))  # fmt: skip
"""Where ctsim's code that calls a controller or estimator lies, and the installed libraries':
never the place to point a user at."""


def where(err: BaseException) -> str:
    """' (file:line)' of the innermost frame `err` passed through in the user's code (or a shipped
    controller's), not in the machinery that called it or a library ('' where none did, and for
    ControllerStopped, whose message says where)."""
    frames = traceback.extract_tb(err.__traceback__) if not isinstance(err, ControllerStopped) else ()
    frames = [f for f in frames if not f.filename.startswith("<") and not str(Path(f.filename).resolve()).startswith(_MACHINERY)]
    return f" ({frames[-1].filename}:{frames[-1].lineno})" if frames else ""


def _takes_readings(function: Callable) -> bool:
    """True for `f(t, readings)`: a controller itself rather than a factory."""
    try:
        return len(inspect.signature(function).parameters) == 2
    except (TypeError, ValueError):
        return False


def _user_line(err: BaseException, path: Path) -> int | str:
    """The line of the user's file where `err` was raised (deepest frame in that file)."""
    tb, line = err.__traceback__, "?"
    while tb is not None:
        if Path(tb.tb_frame.f_code.co_filename) == path:
            line = tb.tb_lineno
        tb = tb.tb_next
    if isinstance(err, SyntaxError) and err.lineno:
        line = err.lineno
    return line


def make(spec: str, params: dict[str, str] | None = None) -> Controller:
    """A controller from a command-line spec: a registered name, `path/to/file.py` or
    `path/to/file.py:Name`, with string parameters. Sees only what is registered so far:
    import it from `bots.behaviours` to have the shipped behaviours registered."""
    params = params or {}
    if spec.endswith(".py") or ".py:" in spec:
        path, _, name = spec.partition(".py")
        return build(load_file(path + ".py", name.lstrip(":") or None), params, spec)
    if spec not in REGISTRY:
        from difflib import get_close_matches

        close = get_close_matches(spec, REGISTRY, n=1)
        hint = f"; did you mean {close[0]!r}?" if close else ""
        raise ControllerError(f"unknown controller {spec!r}{hint} (known: {', '.join(sorted(REGISTRY))})")
    return build(REGISTRY[spec], params, spec)


def reset(controller: Controller, robot: RobotSpec) -> None:
    """Call the controller's optional `reset(robot)`."""
    if hasattr(controller, "reset"):
        controller.reset(robot)
