"""A stand-in for `sim.lab.student.Student` that runs a trusted file in this process: for tests
of the checkers' diagnoses over many files (a class of wrong submissions), where the sandbox's
start per file would cost minutes and test nothing of the diagnosis. Values come back as the
sandbox returns them (`guest.plain`: lists, numbers), exceptions as the sandbox reports them."""

from __future__ import annotations

import importlib.util
import itertools
import math
import traceback
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from sim.lab.student import StudentError, command
from sim.sandbox import Limits
from sim.sandbox.guest import plain

_names = itertools.count()


class LocalStudent:
    """`Student`'s interface over a module loaded here (its arguments as Student takes them)."""

    def __init__(self, path: str | Path, modules: tuple[str, ...] = (), cpu: float = 0.0, folder: bool = False, degraded: bool = False,
                 wall: float = math.inf):  # fmt: skip
        self.path, self.wall, self.spent, self.degraded = str(path), wall, False, False
        self.box = SimpleNamespace(limits=Limits())
        spec = importlib.util.spec_from_file_location(f"ctsim_local_student_{next(_names)}", path)
        self.module = importlib.util.module_from_spec(spec)
        self.objects: dict[int, Any] = {}
        self._guard(lambda: spec.loader.exec_module(self.module), "loading your file", "load")

    def _guard(self, thunk: Callable[[], Any], what: str, kind: str = "raised") -> Any:
        try:
            return thunk()
        except Exception as err:  # noqa: BLE001 (the student's code: anything may come)
            lines = [f.lineno for f in traceback.extract_tb(err.__traceback__) if Path(f.filename) == Path(self.path)]
            line = lines[-1] if lines else None
            detail = f"{what} raised {type(err).__name__}" + (f" at line {line}" if line else "")
            raise StudentError(kind, f"{detail}: {err}", detail, type(err).__name__, line, isinstance(err, ValueError)) from None

    def begin(self, budget: float) -> None:
        pass

    def take_output(self) -> str:
        return ""

    def call(self, name: str, *args: Any) -> Any:
        return self._guard(lambda: plain(getattr(self.module, name)(*args)), f"{name}()")

    def new(self, name: str, **kwargs: Any) -> int:
        handle = len(self.objects) + 1
        self.objects[handle] = self._guard(lambda: getattr(self.module, name)(**kwargs), f"{name}()")
        return handle

    def method(self, handle: int, name: str, *args: Any, attribute: str | None = None, what: str = "") -> Any:
        target = self.objects[handle]
        result = self._guard(lambda: getattr(target, name)(*args), what or f"{name}()")
        return plain(getattr(target, attribute) if attribute else result)

    def feed(self, handle: int, name: str, series: list[tuple], attribute: str, name_call: Callable[[int], str]) -> list:
        target, values = self.objects[handle], []
        for index, args in enumerate(series):
            self._guard(lambda args=args: getattr(target, name)(*args), name_call(index))
            values.append(plain(getattr(target, attribute)))
        return values

    def step(self, handle: int, t: float, readings: Any, what: str):
        from sim.sandbox.guest import command as as_list

        return command(as_list(self._guard(lambda: self.objects[handle].step(t, readings), what)), what)

    def close(self) -> None:
        pass

    def __enter__(self) -> LocalStudent:
        return self

    def __exit__(self, *exc: object) -> None:
        pass
