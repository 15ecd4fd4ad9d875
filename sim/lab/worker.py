"""The process that runs a student's file: it loads the file, then answers requests from the
checker over a pipe (call a function, make an object, call its method, step a controller).

It never sees ground truth or expected values, only the inputs of each request. Everything it
sends back is plain data (numbers, strings, lists, numpy arrays, command tuples), so the checker
never unpickles an object of the student's making. The student's own imports of the world, the
run loop or the checker are refused with a message saying why.
"""

from __future__ import annotations

import builtins
import importlib.util
import io
import sys
import traceback
from pathlib import Path
from typing import Any

import numpy as np

STUDENT_MODULE = "ctsim_student"
GROUND_TRUTH = ("sim.run", "sim.world", "sim.lab", "sim.analysis", "sim.views", "sim.cli", "sim.bridge", "sim.experiments", "pymunk")
"""Modules that hold or compute the world's ground truth (or the checker's expectations)."""
ALLOWED_INSIDE = ("sim.world.readings", "sim.world.Readings")


class ForbiddenImport(ImportError):
    """The student's code imported a module it may not use."""


def _forbidden(name: str, extra: tuple[str, ...]) -> str | None:
    """The refused prefix that `name` falls under, or None."""
    if any(name == a or name.startswith(a + ".") for a in ALLOWED_INSIDE):
        return None
    return next((p for p in GROUND_TRUTH + extra if name == p or name.startswith(p + ".")), None)


def guard_imports(extra: tuple[str, ...]) -> None:
    """Refuse imports of ground-truth modules (and `extra`) made by the student's module."""
    original = builtins.__import__

    def checked(name, globals=None, locals=None, fromlist=(), level=0):  # noqa: A002 (builtins' signature)
        if level == 0 and globals is not None and globals.get("__name__") == STUDENT_MODULE:
            targets = [f"{name}.{item}" for item in fromlist if item != "*"] if fromlist else [name]
            for target in targets:
                refused = _forbidden(target, extra)
                if refused:
                    why = "the world's ground truth and the checker" if refused in GROUND_TRUTH else "this exercise asks you to write it yourself"
                    raise ForbiddenImport(f"import of {target} is not allowed here ({why}); the robot's code sees only its readings")
        return original(name, globals, locals, fromlist, level)

    builtins.__import__ = checked


def describe(err: BaseException, path: str) -> dict[str, Any]:
    """What went wrong, as plain data: exception type, message, the student's line."""
    line = None
    for frame in traceback.extract_tb(err.__traceback__):
        if Path(frame.filename) == Path(path):
            line = frame.lineno
    if isinstance(err, SyntaxError) and err.lineno and Path(err.filename or "") == Path(path):
        line = err.lineno
    return {
        "type": type(err).__name__,
        "message": str(err).splitlines()[0] if str(err) else "",
        "line": line,
        "value_error": isinstance(err, ValueError),
        "forbidden": isinstance(err, ForbiddenImport),
    }


def plain(value: Any) -> Any:
    """`value` as plain data; anything else becomes {'__type__': its type name}."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, float, np.integer, np.floating)):
        return float(value)
    if isinstance(value, np.ndarray):
        return value.astype(np.float64) if value.dtype.kind in "biuf" else {"__type__": f"array of {value.dtype}"}
    if isinstance(value, (tuple, list)):
        return [plain(v) for v in value]
    return {"__type__": type(value).__name__}


def command_tuple(command: Any) -> tuple:
    """A controller's command as ('wheels'|'twist'|'curve', numbers...) or ('bad', type name)."""
    from bots.commands import CurveCommand, Twist, WheelSpeeds

    if isinstance(command, WheelSpeeds):
        return ("wheels", float(command.left), float(command.right))
    if isinstance(command, Twist):
        return ("twist", float(command.v), float(command.omega))
    if isinstance(command, CurveCommand):
        return ("curve", float(command.kappa_n), float(command.beta), float(command.v_n))
    return ("bad", type(command).__name__)


def _load(path: str):
    spec = importlib.util.spec_from_file_location(STUDENT_MODULE, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[STUDENT_MODULE] = module
    spec.loader.exec_module(module)
    return module


def _entry(module, name: str):
    if not hasattr(module, name):
        raise AttributeError(f"your file defines no {name!r} (keep the name the template gives)")
    return getattr(module, name)


def serve(conn, path: str, extra_forbidden: tuple[str, ...]) -> None:
    """Load the student's file and answer requests until the pipe closes."""
    import bots.commands  # noqa: F401  (loaded before the guard; readings load when a request brings some)

    sys.stdout = io.StringIO()  # a student's print must not reach the grader's output
    guard_imports(tuple(extra_forbidden))
    try:
        module = _load(path)
    except BaseException as err:  # noqa: BLE001 (the student's code: anything may come)
        conn.send(("error", describe(err, path)))
        return
    conn.send(("ok", None))
    objects: dict[int, Any] = {}
    while True:
        try:
            op, args = conn.recv()
        except EOFError:
            return
        sys.stdout = io.StringIO()
        try:
            conn.send(("ok", _answer(module, objects, op, args)))
        except BaseException as err:  # noqa: BLE001
            conn.send(("error", describe(err, path)))


def _answer(module, objects: dict[int, Any], op: str, args: tuple) -> Any:
    if op == "call":  # (name, args)
        name, call_args = args
        return plain(_entry(module, name)(*call_args))
    if op == "new":  # (handle, name, kwargs)
        handle, name, kwargs = args
        objects[handle] = _entry(module, name)(**kwargs)
        return None
    if op == "method":  # (handle, method, args, attribute to return after the call or None)
        handle, method, call_args, attribute = args
        result = getattr(objects[handle], method)(*call_args)
        return plain(getattr(objects[handle], attribute) if attribute else result)
    if op == "step":  # (handle, t, readings)
        handle, t, readings = args
        return command_tuple(objects[handle].step(t, readings))
    raise ValueError(f"unknown request {op!r}")

