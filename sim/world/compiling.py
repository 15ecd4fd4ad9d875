"""Compile the world's kernels for the types of a world's arrays: on a machine whose numba cache
does not hold them yet (the first run after an install or a change), in two processes at once.

numba compiles in one thread, and the first run's compile is most of its time: half a minute of
CPU for a c't-Bot in the maze (`bench/run.py -k first_run`). The kernels do not share their
compile work much, so a second process compiles some of them into numba's cache while this one
compiles the rest, and this one then loads those from the cache. Where the cache already holds
them (every later run), nothing is started. `PROGRESS` says what is going on while it lasts.
"""

from __future__ import annotations

import pickle
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

HELPER_TIMEOUT_S = 1800.0
"""Longest wait for the second process (s), far beyond its minutes on a loaded machine."""
PROGRESS: Callable[[str], None] | None = None
"""Called with a line of text when kernels are compiled, and every TICK_S seconds while they are
(the command line prints it), None: silent."""
TICK_S = 5.0


def compiled_for(kernel: Any, *arguments: Any) -> Callable:
    """`kernel` compiled (or loaded from numba's cache) for the types of `arguments`, to be called
    without numba's dispatch, which finds the type of every argument on every call: 0.05-0.1 µs
    an array, some 3 µs of a world step's 48 arrays on a 2-core VM. For a caller whose arguments
    keep these types (dtype, dimensions, layout) on every call only: other types are misread, not
    refused."""
    return kernel.compile(_types(kernel, arguments))


def compile_all(jobs: list[tuple[Any, tuple]], elsewhere: int = 1) -> list[Callable]:
    """`compiled_for(kernel, *arguments)` of every (kernel, arguments) job, in their order. When
    numba's cache lacks two or more of them, the last `elsewhere` of those missing are compiled
    by a second process at the same time (put the largest kernels last)."""
    typed = [(kernel, _types(kernel, arguments)) for kernel, arguments in jobs]
    missing = [(kernel, types) for kernel, types in typed if not _in_cache(kernel, types)]
    helper = None
    if len(missing) >= 2 and elsewhere > 0:
        helper = _start([(kernel.py_func.__module__, kernel.py_func.__name__, types) for kernel, types in missing[-elsewhere:]])
    if missing and PROGRESS is not None:
        PROGRESS(f"compiling the simulator's kernels for this machine (first run only): {', '.join(k.py_func.__name__ for k, _ in missing)}")
    started = time.perf_counter()
    own = missing[: len(missing) - elsewhere] if helper is not None else missing
    done = [0]
    with _ticking(lambda: f"compiling: {done[0]} of {len(missing)} kernels done, {time.perf_counter() - started:.0f} s so far (first run only)",
                  bool(missing) and PROGRESS is not None):  # fmt: skip
        for kernel, types in own:
            kernel.compile(types)
            done[0] += 1
        if helper is not None:  # whatever went wrong there is compiled here below
            try:
                helper.wait(timeout=HELPER_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                helper.kill()
                helper.wait()
        compiled = [kernel.compile(types) for kernel, types in typed]
    if missing and PROGRESS is not None:
        PROGRESS(f"compiled in {time.perf_counter() - started:.0f} s; later runs load them from numba's cache")
    return compiled


@contextmanager
def _ticking(line: Callable[[], str], on: bool) -> Iterator[None]:
    """`PROGRESS(line())` every TICK_S seconds meanwhile (if `on`), from a thread that ends with it
    (a sweep forks its workers only from a process running one thread)."""
    if not on:
        yield
        return
    stop = threading.Event()

    def tick() -> None:
        while not stop.wait(TICK_S):
            PROGRESS(line())

    ticker = threading.Thread(target=tick, name="ctsim compile progress", daemon=True)
    ticker.start()
    try:
        yield
    finally:
        stop.set()
        ticker.join()


def _types(kernel: Any, arguments: tuple) -> tuple:
    return tuple(kernel.typeof_pyval(argument) for argument in arguments)


def _in_cache(kernel: Any, types: tuple) -> bool:
    """Whether numba's cache holds `kernel` for `types` (numba's own key); True where that cannot
    be told (no cache, another numba's layout): then nothing is started."""
    try:
        cache = kernel._cache
        key = cache._index_key(types, kernel.targetctx.codegen())
        return key in cache._cache_file._load_index()
    except Exception:  # noqa: BLE001 (a numba without these internals: compile here, as always)
        return True


def _start(jobs: list[tuple[str, str, tuple]]) -> subprocess.Popen | None:
    """A process that compiles `jobs` (module, kernel name, numba types) into numba's cache."""
    try:
        helper = subprocess.Popen([sys.executable, "-m", __name__], stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        helper.stdin.write(pickle.dumps(jobs))
        helper.stdin.close()
        return helper
    except OSError:
        return None


def _compile_jobs() -> None:
    """The second process: compile the pickled jobs on stdin (written by `_start`, trusted)."""
    import importlib

    for module, name, types in pickle.load(sys.stdin.buffer):
        getattr(importlib.import_module(module), name).compile(types)


if __name__ == "__main__":
    _compile_jobs()
