"""What a new user waits for: `ctsim run` (the main job, as the README gives it: a c't-Bot with
realistic noise solving the maze to its goal, its recording, figures and report.html) in a clean
process with an empty numba cache, beside the same command once the cache holds the kernels.

`first_run_s` is the wall time of `ctsim run` with a fresh NUMBA_CACHE_DIR (numba then keeps
every kernel there, never in the tree's __pycache__): start-up, compiling every kernel the run
needs, the whole run and its files. `first_run_one_process_s` is the same with every kernel compiled in the one process (no
helper process, `sim.world.compiling.compile_all`), `first_run_warm_s` the command with the cache filled
by the first: what every later run pays. The machine is shared: read them as ratios.
`suite_s` is the README's test command as a whole (bar: 5 minutes on a quiet machine).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
RUN = ["run"]
ONE_PROCESS = "import sim.world.compiling as c; c.WORKERS = 0; "


def _timed(cache: str, out: str, prelude: str = "") -> float:
    """Wall seconds of `ctsim run` in a clean subprocess with numba's cache at `cache`."""
    code = f"import sys; {prelude}from sim.cli.entry import main; sys.exit(main({RUN + ['--out', out]!r}))"
    env = {**os.environ, "NUMBA_CACHE_DIR": cache}
    started = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], cwd=ROOT, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - started


def _suite() -> float:
    """Wall seconds of the README's test command (`python -m pytest`) in a clean subprocess, with
    numba's cache as the working tree has it (a fresh clone compiles on top of this)."""
    started = time.perf_counter()
    subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider"], cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - started


def figures(scale: float):  # noqa: ARG001 (a first run is as long as it is)
    """(name, unit, thunk) of the first run, one process's compile and the warm run."""
    results: dict[str, float] = {}

    def measure() -> dict[str, float]:
        if not results:
            with tempfile.TemporaryDirectory() as one, tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
                results["one"] = _timed(one, out, ONE_PROCESS)
                results["first"] = _timed(cache, out)
                results["warm"] = _timed(cache, out)
        return results

    yield "first_run_s", "s (`ctsim run`, the whole main job, empty numba cache; bar <= 20 on a quiet machine)", lambda: measure()["first"]
    yield "first_run_one_process_s", "s (the same, every kernel compiled in one process)", lambda: measure()["one"]
    yield "first_run_warm_s", "s (the same command again, kernels from the cache)", lambda: measure()["warm"]
    yield "first_run_over_warm", "(first / warm, same bench run)", lambda: measure()["first"] / measure()["warm"]
    yield "suite_s", "s (python -m pytest, the whole suite: run it alone, -k suite_s)", _suite
