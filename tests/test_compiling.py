"""`sim.world.compiling.compile_all`: with numba's cache cold, compile processes (one per core)
compile the kernels into the cache side by side, and this one then loads them from there."""

from __future__ import annotations

import importlib
import sys

import numpy as np

from sim.world import compiling

KERNELS = '''
import numba

@numba.njit(cache=True)
def double(x):
    return 2.0 * x

@numba.njit(cache=True)
def total(values):
    s = 0.0
    for v in values:
        s += v
    return s
'''


def test_a_cold_cache_is_filled_by_compile_processes_and_loaded_here(tmp_path, monkeypatch):
    (tmp_path / "tiny_kernels.py").write_text(KERNELS)  # a module of its own: its cache starts empty
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setenv("PYTHONPATH", f"{tmp_path}:{':'.join(sys.path)}")  # the second process finds it too
    tiny = importlib.import_module("tiny_kernels")
    lines: list[str] = []
    monkeypatch.setattr(compiling, "PROGRESS", lines.append)
    monkeypatch.setattr(compiling, "WORKERS", 2)
    double, total = compiling.compile_all([(tiny.double, (1.0,)), (tiny.total, (np.zeros(3),))])
    assert double(1.5) == 3.0 and total(np.arange(4.0)) == 6.0
    assert sum(tiny.total.stats.cache_hits.values()) == sum(tiny.double.stats.cache_hits.values()) == 1  # compiled there, loaded here
    assert sum(tiny.double.stats.cache_misses.values()) == 0  # nothing compiled here
    assert "in 2 processes: double, total" in lines[0] and lines[-1].startswith("compiled 2 kernels in")
    assert all(line.startswith("compiling: ") and "of 2 kernels done" in line for line in lines[1:-1])  # every PROGRESS_EVERY meanwhile
    lines.clear()
    compiling.compile_all([(tiny.double, (1.0,)), (tiny.total, (np.zeros(3),))])
    assert lines == []  # warm: nothing said, nothing started


def test_no_compile_processes_compiles_every_kernel_here(tmp_path, monkeypatch):
    """WORKERS 0 (the bench's `first_run_one_process_s`): nothing is started, the kernels are
    compiled in this process, and the line says so."""
    (tmp_path / "tiny_kernels_here.py").write_text(KERNELS)
    monkeypatch.syspath_prepend(str(tmp_path))
    tiny = importlib.import_module("tiny_kernels_here")
    lines: list[str] = []
    monkeypatch.setattr(compiling, "PROGRESS", lines.append)
    monkeypatch.setattr(compiling, "WORKERS", 0)
    started = compiling.start([(tiny.double, (1.0,)), (tiny.total, (np.zeros(3),))])
    assert started.helpers == [] and "in this process: double, total" in lines[0]
    double, total = started.wait()
    assert double(1.5) == 3.0 and total(np.arange(4.0)) == 6.0
    assert sum(tiny.double.stats.cache_misses.values()) == 1  # compiled here
