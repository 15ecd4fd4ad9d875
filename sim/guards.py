"""What a controller may change of the process it runs in, put back after each step of a run,
so that a mistake in a controller's code cannot take the run's guards with it: its signal
handlers (Ctrl-C, SIGTERM, the step timer's SIGALRM), blocked signals, the step timer itself
(its interval and its next expiry), the recursion limit, stdout and stderr (the objects and the
descriptors 1 and 2 under them, redirected with os.dup2 too), `os._exit` (and `posix._exit`) from
a thread, a fork (its child leaves at once: `_in_child`), and the module attributes of ctsim, numpy and
the standard library modules ctsim writes its files and lines with (json, os, io, csv, builtins),
and the methods of their classes. The guard holds from the run's first user code (the resets)
to its end; what the controllers' and estimators' constructors replace in those modules and
classes is put back as soon as they are made, before ctsim writes anything (`making`: `simulate`,
`ctsim run`).

A controller is the user's own code (or, in a contest, someone else's, which runs sandboxed):
these guards catch mistakes, not an attacker; code that means harm can still use ctypes. What a
guard put back is said once per kind at the end of the run (`Guard.notes`).

After every step an attribute read catches an exit from a thread and one system call the step
timer's next expiry (a controller that re-arms it far ahead would switch off the step time limit
for the steps that follow); every EVERY-th step the full check (a handful of calls and a few
system calls, about 5 µs) puts back the rest, once for all robots; the module snapshot is compared
only when the run ends or fails.
"""

from __future__ import annotations

import _signal
import importlib
import inspect
import operator
import os
import signal
import sys
import sysconfig
import threading
import traceback
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import Any

_NATIVE = importlib.import_module(os.name)
"""posix (or nt): the module os._exit comes from, a second way to call it."""
RECURSION_LIMIT = sys.getrecursionlimit()
"""The recursion limit ctsim started with: a controller that lowers it gets it back."""
_REAL_EXIT = os._exit
_SIGNALS = tuple(s for s in (getattr(signal, "SIGINT", None), getattr(signal, "SIGTERM", None), getattr(signal, "SIGALRM", None)) if s is not None)
EVERY = 32
"""Steps between two full checks (`Guard.after_step`): a controller's change stands at most this
many steps (0.32 s of a run at dt 0.01, a few milliseconds of a run's wall time; at 8 the checks
were a sixth of the run loop's own work a step)."""
_WATCHED = ("numpy", "sim", "bots", "json", "os", "posix", "io", "csv", "builtins")
"""Modules (and their submodules) whose attributes a controller must not replace: ctsim's and
numpy's, and the standard library's that ctsim writes its files and lines with (a replaced
json.dumps once left summary.json `{}`)."""
TIMER_SLACK = 1e-3
"""Seconds the step timer's next expiry may lie beyond its interval (the clock's rounding)."""


class _Forks:
    """Whether a run is going in this process (`running`): a fork made then is user code's."""

    running = False


def _in_child() -> None:
    """A fork's child made while a run goes (a controller's or an estimator's `os.fork()`) leaves
    at once, before it returns into user code: the run and its files belong to the parent, and a
    child that never returned (an estimator forking a busy loop each update) was a fork bomb the
    run's end did not stop. A sweep's workers, forked between runs, are not."""
    if _Forks.running:
        _REAL_EXIT(1)


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_in_child)


class ControllerBrokeOut(Exception):
    """A controller did what ends a run (`os._exit` from a thread, replacing numpy or ctsim)."""


def _snapshot() -> dict[str, tuple[ModuleType, dict[str, Any]]]:
    return {name: (module, vars(module).copy()) for name, module in list(sys.modules.items())
            if isinstance(module, ModuleType) and name.split(".")[0] in _WATCHED}


def _same(before: dict[str, Any], now: Mapping[str, Any]) -> bool:
    """Whether a namespace holds the very objects it held, told in C (no `__eq__` of theirs runs):
    most of a few hundred modules and classes, in well under a millisecond."""
    return len(before) == len(now) and all(map(operator.is_, before.values(), now.values())) and before.keys() == now.keys()


_MUTABLE = 1 << 9, 1 << 8
"""Py_TPFLAGS_HEAPTYPE and Py_TPFLAGS_IMMUTABLETYPE: a class whose attributes can be set is a heap
type that is not immutable (numpy's ndarray and Generator, builtins' int, cannot be patched)."""
_CLASSES: dict[str, tuple[ModuleType, tuple[type, ...]]] = {}
"""The patchable classes each watched module defines, found once per module (a few ms in all)."""


def _classes(modules: dict[str, tuple[ModuleType, dict[str, Any]]]) -> dict[type, dict[str, Any]]:
    """The attributes of every patchable class the watched modules define (a method of World
    or of a numpy class a controller replaces is a replaced function too)."""
    found = {}
    for name, (module, attributes) in modules.items():
        known = _CLASSES.get(name)
        if known is None or known[0] is not module:
            heap, immutable = _MUTABLE
            mine = tuple(value for value in attributes.values() if isinstance(value, type) and value.__module__ == name
                         and value.__flags__ & heap and not value.__flags__ & immutable)  # fmt: skip
            known = _CLASSES[name] = (module, mine)
        for cls in known[1]:
            found[cls] = vars(cls).copy()
    return found


def _code(value: Any) -> bool:
    """Whether a module's or class's attribute is code (a function, class, method, descriptor or
    module), what a controller must not replace; data (a class's counters, a cache) may change."""
    return callable(value) or isinstance(value, ModuleType | classmethod | staticmethod | property)


_MISSING = object()


class Snapshot:
    """The code in the watched modules and their classes at one moment (`_snapshot`, `_classes`):
    `put_back` restores what was replaced since and names it."""

    def __init__(self) -> None:
        self.modules = _snapshot()
        self.classes = _classes(self.modules)

    def put_back(self, ours: object = None) -> str:
        """The functions, classes and modules in the watched modules, and the methods of their
        classes, replaced, deleted or (on a class) added since the snapshot, put back; named ('' for
        none). `ours`: a replacement in place on purpose (the guard's own os._exit), left alone."""
        changed = []
        for name, (owner, before) in self.modules.items():
            now = vars(owner)
            if _same(before, now):
                continue
            for key, value in before.items():
                current = now.get(key, _MISSING)
                if current is not value and current is not ours and _code(value):
                    changed.append(f"{name}.{key}")
                    setattr(owner, key, value)
        for cls, before in self.classes.items():
            now = vars(cls)
            if _same(before, now):
                continue
            for key in before.keys() | now.keys():
                value, current = before.get(key, _MISSING), now.get(key, _MISSING)
                if current is not value and (_code(value) or _code(current)):
                    changed.append(f"{cls.__module__}.{cls.__qualname__}.{key}")
                    if value is _MISSING:
                        delattr(cls, key)
                    else:
                        setattr(cls, key, value)
        return ", ".join(changed[:5]) + (f" and {len(changed) - 5} more" if len(changed) > 5 else "")


@contextmanager
def making() -> Iterator[list[str]]:
    """The user's controllers and estimators made inside: what their constructors replace in the
    watched modules and classes is put back on leaving (also when one fails), before the run and
    before ctsim writes a file with them; the list yielded then holds the note that says so, if any."""
    snapshot = Snapshot()
    notes: list[str] = []
    try:
        yield notes
    finally:
        replaced = snapshot.put_back()
        if replaced:
            notes.append(f"a controller or estimator replaced {replaced} while it was made; ctsim put {_them(replaced)} back")


def _them(replaced: str) -> str:
    return "them" if ", " in replaced or " and " in replaced else "it"


class Guard:
    """The process state a run relies on, taken at its start (after its handlers and timer are
    set); `check()` after every step puts back what a controller changed."""

    def __init__(self) -> None:
        self.main = threading.main_thread() is threading.current_thread()
        # (the handlers as the C module gives them: signal.getsignal turns each into an enum member where it
        # can, trying and failing with an exception for a function, most of a check's cost)
        self.handlers = {s: _signal.getsignal(s) for s in _SIGNALS} if self.main else {}
        self.timer = signal.getitimer(signal.ITIMER_REAL) if self.main and hasattr(signal, "getitimer") else None
        self.streams = [sys.stdout, sys.stderr]
        self._plain: list[set[str]] = [set(), set()]  # per stream, attribute names it had with no method hidden (`_hides`)
        self.descriptors = {fd: os.dup(fd) for fd in (1, 2) if _open(fd)}
        self.targets = {fd: _identity(copy) for fd, copy in self.descriptors.items()}
        self.snapshot = Snapshot()
        self.exited: str | None = None
        self.notes: dict[str, str] = {}
        self._exit = os._exit
        self._hook = self._guarded_exit  # (one bound method: the run's own replacement, never blamed on a controller)

    def __enter__(self) -> Guard:
        os._exit = _NATIVE._exit = self._hook
        _Forks.running = True
        return self

    def __exit__(self, *exc: object) -> None:
        os._exit = _NATIVE._exit = self._exit
        _Forks.running = False
        self.exited = None  # (said already, if the run ended by it)
        self.handlers, self.timer = {}, None  # (the run's clock and handlers are put away by their owners now)
        self.check()
        self._put_back_descriptors()
        replaced = self.replaced()
        if replaced:
            self.notes["modules"] = f"the controller replaced {replaced}; ctsim put {_them(replaced)} back"
        for descriptor in self.descriptors.values():
            os.close(descriptor)

    def _guarded_exit(self, status: int = 0) -> None:
        """os._exit during a run: from the main thread a controller's exit (SystemExit), from
        another thread the end of that thread and of the run, its data kept."""
        where = threading.current_thread().name
        if threading.current_thread() is not threading.main_thread():
            self.exited = f"called os._exit({status}) from the thread {where!r}"
        leaving = SystemExit(status)
        leaving.via = "os._exit"  # (said so: `bots.controller.did`)
        raise leaving

    def after_step(self, step: int) -> None:
        """After every step: an os._exit from a thread ends the run; every EVERY-th step the rest
        of `check` (an exit costs an attribute read; the rest a few µs, a thirty-second of that per
        step)."""
        if self.exited is not None:
            raise ControllerBrokeOut(self.exited)
        if self.timer is not None and self.timer[1] and signal.getitimer(signal.ITIMER_REAL)[0] > self.timer[1] + TIMER_SLACK:
            self._restart_timer()
        if not step % EVERY:
            self.check()

    def check(self) -> None:
        """After a step: signal handlers, blocked signals, the step timer, the recursion limit and
        stdout/stderr are put back; ControllerBrokeOut after an os._exit from a thread."""
        if self.main:
            for number, handler in self.handlers.items():
                if _signal.getsignal(number) is not handler:
                    signal.signal(number, handler)
                    self.notes.setdefault(f"signal {number}", f"the controller changed the handler of {signal.Signals(number).name}; ctsim put its own back")
            # (the C module's call: a set of ints, without signal.py's conversion of each into an enum member)
            blocked = _signal.pthread_sigmask(signal.SIG_BLOCK, ()) if hasattr(_signal, "pthread_sigmask") else set()
            if not blocked.isdisjoint(_SIGNALS):
                signal.pthread_sigmask(signal.SIG_UNBLOCK, _SIGNALS)
                self.notes.setdefault("mask", "the controller blocked ctsim's signals; ctsim unblocked them")
            if self.timer is not None and self.timer[1]:
                value, interval = signal.getitimer(signal.ITIMER_REAL)
                if interval != self.timer[1] or value > interval + TIMER_SLACK:
                    self._restart_timer()
        if sys.getrecursionlimit() < RECURSION_LIMIT:
            sys.setrecursionlimit(RECURSION_LIMIT)
            self.notes.setdefault("recursion", f"the controller lowered the recursion limit; ctsim put it back to {RECURSION_LIMIT}")
        out, err = self.streams
        if sys.stdout is not out or sys.stderr is not err or out.closed or err.closed or self._hides(0) or self._hides(1):
            self._put_back_streams()
        else:
            self._put_back_descriptors()
        if self.exited is not None:
            raise ControllerBrokeOut(self.exited)

    def _hides(self, k: int) -> bool:
        """Whether an attribute of stream `k` itself hides a method of its class (`_shadowed`); told
        from the names of its attributes alone while they are names it had with none hidden (a
        look at each name's class attribute was a third of a check)."""
        stream = self.streams[k]
        names = getattr(stream, "__dict__", {})
        if names.keys() == self._plain[k]:
            return False
        if _shadowed(stream):
            return True
        self._plain[k] = set(names)
        return False

    def _restart_timer(self) -> None:
        signal.setitimer(signal.ITIMER_REAL, self.timer[1], self.timer[1])
        self.notes.setdefault("timer", "the controller stopped or re-armed the step timer; ctsim started it again")

    def _put_back_streams(self) -> None:
        self._put_back_descriptors()
        for k, name in enumerate(("stdout", "stderr")):
            stream = self.streams[k]
            for key in _shadowed(stream):  # (sys.stdout.write = None: the method back)
                delattr(stream, key)
            if stream.closed:
                stream = self.streams[k] = os.fdopen(os.dup(k + 1), "w", buffering=1, encoding=getattr(stream, "encoding", None) or "utf-8", errors="backslashreplace")
            setattr(sys, name, stream)
        self.notes.setdefault("streams", "the controller closed or replaced stdout or stderr (or a method of theirs); ctsim put them back")

    def _put_back_descriptors(self) -> None:
        for fd, copy in self.descriptors.items():
            if _identity(fd) != self.targets[fd]:
                os.dup2(copy, fd)
                self.notes.setdefault("descriptors", "the controller closed or redirected file descriptor 1 or 2; ctsim put it back")

    def replaced(self) -> str:
        """What a controller replaced in the watched modules and their classes since the snapshot,
        put back; named ('' for none: `Snapshot.put_back`)."""
        return self.snapshot.put_back(self._hook)


_ROOT = Path(__file__).resolve().parents[1]
_KNOWN = tuple({str(_ROOT / "sim"), str(_ROOT / "bots"), *(sysconfig.get_paths()[key] for key in ("stdlib", "platstdlib", "purelib", "platlib"))})
"""Where ctsim's and the installed libraries' code lives: never the user's."""


def user_code_folders(objects: list[object]) -> tuple[str, ...]:
    """The folders of the user's code among `objects` (controllers, estimators): where the files
    their classes came from lie, unless that is ctsim's or an installed library's."""
    folders = set()
    for obj in objects:
        try:
            source = inspect.getsourcefile(type(obj))
        except TypeError:  # a class made at run time, or a builtin
            continue
        if source is not None and not str(Path(source).resolve()).startswith(_KNOWN):
            folders.add(str(Path(source).resolve().parent) + os.sep)
    return tuple(sorted(folders))


def foreign_frame(err: BaseException, user_folders: tuple[str, ...]) -> str | None:
    """Where the user's code (in `user_folders`, `user_code_folders`) ran in the traceback of a
    failure inside ctsim, innermost first ('file:line'): a method a controller patched into a
    class of ctsim's; None when none did (then the failure is ctsim's)."""
    if not user_folders:
        return None
    for frame in reversed(traceback.extract_tb(err.__traceback__)):
        where = str(Path(frame.filename).resolve())
        if not frame.filename.startswith("<") and where.startswith(user_folders) and not where.startswith(_KNOWN):  # (ctsim inside the user's folder stays ctsim)
            return f"{frame.filename}:{frame.lineno}"
    return None


def _shadowed(stream: object) -> list[str]:
    """The methods of a stream that an attribute of the object itself hides (set by a controller)."""
    return [key for key in getattr(stream, "__dict__", {}) if callable(getattr(type(stream), key, None))]


def _open(fd: int) -> bool:
    return _identity(fd) is not None


def _identity(fd: int) -> tuple[int, int] | None:
    """The file a descriptor stands for (device, inode), or None when it is closed."""
    try:
        info = os.fstat(fd)
    except OSError:
        return None
    return info.st_dev, info.st_ino
