"""Compile kernels for the types of their arguments: where numba's cache does not hold them yet
(the first run after an install or a change), in compile processes, one per core, all at once.

numba compiles in one thread, and the first run's compile is most of its time: some 22 s
of CPU for a c't-Bot in the maze (`bench/run.py -k first_run`). The kernels share little of
their compile work, so the missing ones are dealt out to as many processes as there are cores
(and kernels), less the compile processes this process still has at work (the odometry's, started
first), which compile them into numba's cache side by side while this process waits and
says so (`PROGRESS`, every PROGRESS_EVERY seconds); this process then loads them all from the
cache. `start` begins it and returns at once, so that the world's kernels and the odometry's
compile together (`compile_all` is `start(...).wait()`). Where the cache already holds them
(every later run), nothing is started.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import time
from collections.abc import Callable
from typing import Any

import numpy as np

HELPER_TIMEOUT_S = 1800.0
"""Longest wait for the compile processes (s), far beyond their minutes on a loaded machine."""
PROGRESS: Callable[[str], None] | None = None
"""Called with a line of text while kernels are compiled (the command line prints it), None: silent."""
PROGRESS_EVERY = 5.0
"""Seconds between two lines of `PROGRESS` while the compile processes work."""
WORKERS = os.cpu_count() or 1
"""Compile processes at most (one per core; 0: none, every kernel compiled in the process that needs it)."""
_IN_FLIGHT: dict[tuple[Any, tuple], subprocess.Popen] = {}
"""(kernel, numba types) -> the compile process of this process compiling it: a later `start`
for the same job waits for that process instead of starting another (a run starts its odometry's
compile first thing, and the odometry asks for it again once made)."""


def compiled_for(kernel: Any, *arguments: Any) -> Callable:
    """`kernel` compiled (or loaded from numba's cache) for the types of `arguments`, to be called
    without numba's dispatch, which finds the type of every argument on every call: 0.05-0.1 µs
    an array, some 3 µs of a world step's 48 arrays on a 2-core VM. For a caller whose arguments
    keep these types (dtype, dimensions, layout) on every call only: other types are misread, not
    refused."""
    return kernel.compile(_types(kernel, arguments))


class Compiling:
    """Kernels being compiled into numba's cache by compile processes (`start`); `wait` gives
    them compiled for their arguments' types, as `compiled_for` does."""

    def __init__(self, jobs: list[tuple[Any, tuple]], workers: int | None = None):
        self.typed = [(kernel, _types(kernel, arguments)) for kernel, arguments in jobs]
        self.missing = [(kernel, types) for kernel, types in self.typed if not _in_cache(kernel, types)]
        self.started = time.perf_counter()
        running = {job: helper for job in self.missing if (helper := _IN_FLIGHT.get(job)) is not None and helper.poll() is None}
        new = [job for job in self.missing if job not in running]
        # a core each, less those of this process's compile processes still at work (the odometry's
        # kernel starts first and compiles longest: the world's beside it in one more process, not
        # two, leave it a core of its own on two)
        if workers is None:  # (WORKERS 0: none, as `workers` 0)
            busy = len({id(helper) for helper in _IN_FLIGHT.values() if helper.poll() is None})
            workers = max(1, WORKERS - busy) if WORKERS else 0
        count = min(len(new), workers)
        # the kernels dealt out from the last (the largest, by the callers' order) round the processes
        shares = [[job for k, job in enumerate(reversed(new)) if k % count == p] for p in range(count)]
        self.helpers = list({id(helper): helper for helper in running.values()}.values())
        for share in shares:
            if (helper := _start(share)) is not None:
                self.helpers.append(helper)
                _IN_FLIGHT.update(dict.fromkeys(share, helper))
        if new and PROGRESS is not None:
            processes = f"{len(shares)} process{'es' if len(shares) != 1 else ''}" if shares else "this process"
            PROGRESS(f"compiling the simulator's kernels for this machine (first run only) in {processes}: "
                     f"{', '.join(k.py_func.__name__ for k, _ in new)}")  # fmt: skip

    def wait(self) -> list[Callable]:
        """The kernels, compiled: loaded from the cache the compile processes filled (whatever
        they could not compile is compiled here)."""
        deadline = self.started + HELPER_TIMEOUT_S
        for helper in self.helpers:
            while helper.poll() is None:
                try:
                    helper.wait(timeout=min(PROGRESS_EVERY, max(deadline - time.perf_counter(), 0.0)))
                except subprocess.TimeoutExpired:
                    if time.perf_counter() >= deadline:
                        helper.kill()
                        helper.wait()
                    elif PROGRESS is not None:
                        done = sum(_in_cache(kernel, types) for kernel, types in self.missing)
                        PROGRESS(f"compiling: {done} of {len(self.missing)} kernels done ({time.perf_counter() - self.started:.0f} s)")
        compiled = [kernel.compile(types) for kernel, types in self.typed]
        if self.missing and PROGRESS is not None:
            count = f"{len(self.missing)} kernel{'s' if len(self.missing) > 1 else ''}"  # (a run starts two groups)
            PROGRESS(f"compiled {count} in {time.perf_counter() - self.started:.0f} s; later runs load them from numba's cache")
        self.helpers, self.missing = [], []
        return compiled


def start(jobs: list[tuple[Any, tuple]], workers: int | None = None) -> Compiling:
    """Begin compiling every (kernel, arguments) job that numba's cache lacks, in up to `workers`
    compile processes (default WORKERS; 0: none, `wait` compiles them here; put the largest kernels
    last); `.wait()` gives them all in their order."""
    return Compiling(jobs, workers)


def compile_all(jobs: list[tuple[Any, tuple]], workers: int | None = None) -> list[Callable]:
    """`compiled_for(kernel, *arguments)` of every (kernel, arguments) job, in their order, those
    numba's cache lacks compiled in compile processes first (`start`)."""
    return start(jobs, workers).wait()


def _types(kernel: Any, arguments: tuple) -> tuple:
    return tuple(_type_of(kernel, argument) for argument in arguments)


_ARRAY_TYPES: dict[tuple, Any] = {}
"""numba's types of arrays by (dtype, aligned struct, dimensions, layout, writeable): numba's own
`typeof` builds a structured dtype's record type afresh every time, and every run types its
world's tables (some 70 arguments: a millisecond or two of its start)."""


def _type_of(kernel: Any, value: Any) -> Any:
    """numba's type of an argument as `kernel.typeof_pyval` gives it, arrays' (also inside tuples) kept."""
    if type(value) is np.ndarray:
        flags = value.flags
        key = (value.dtype, value.dtype.isalignedstruct, value.ndim, "C" if flags.c_contiguous else "F" if flags.f_contiguous else "A", flags.writeable)
        found = _ARRAY_TYPES.get(key)
        if found is None:
            found = _ARRAY_TYPES[key] = kernel.typeof_pyval(value)
        return found
    if isinstance(value, tuple):  # (a plain or named tuple: numba's `typeof` of one, from its items' types)
        from numba.core.types import BaseTuple

        return BaseTuple.from_types([_type_of(kernel, item) for item in value], type(value))
    return kernel.typeof_pyval(value)


def _in_cache(kernel: Any, types: tuple) -> bool:
    """Whether `kernel` is compiled for `types` in this process or numba's cache holds it (numba's
    own key); True where that cannot be told (no cache, another numba's layout): then nothing is
    started."""
    if types in kernel.overloads:  # (loaded or compiled here already: no need to read the cache's index)
        return True
    try:
        cache = kernel._cache
        key = cache._index_key(types, kernel.targetctx.codegen())
        return key in cache._cache_file._load_index()
    except Exception:  # noqa: BLE001 (a numba without these internals: compile here, as always)
        return True


def _start(jobs: list[tuple[Any, tuple]]) -> subprocess.Popen | None:
    """A process that compiles `jobs` (kernel, numba types) into numba's cache."""
    try:
        helper = subprocess.Popen([sys.executable, "-m", __name__], stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        helper.stdin.write(pickle.dumps([(kernel.py_func.__module__, kernel.py_func.__name__, types) for kernel, types in jobs]))
        helper.stdin.close()
        return helper
    except OSError:
        return None


def _compile_jobs() -> None:
    """A compile process: compile the pickled jobs on stdin (written by `_start`, trusted)."""
    import importlib

    for module, name, types in pickle.load(sys.stdin.buffer):
        getattr(importlib.import_module(module), name).compile(types)


if __name__ == "__main__":
    _compile_jobs()
