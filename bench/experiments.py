"""Many-runs benchmarks: a sweep on local processes and on Dask against a plain loop of the same
runs, and the vectorised Gymnasium environment against N separate environments."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from sim.experiments import Dask, Processes, Serial, load_results, sweep
from sim.experiments.store import PARTS


def _sweep_seconds(runner: Any, runs: int, duration: float) -> float:
    """Wall time of a sweep of `runs` seeds of the default maze run on a started engine (local
    workers start inside it, a Dask cluster before it)."""
    spec = {"base": {"duration": duration}, "axes": {"seed": list(range(runs))}}
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        try:
            sweep(spec, folder, runner, progress=False)
        finally:
            runner.close()
        return time.perf_counter() - start


def sweep_engines(runs: int, duration: float = 20.0, rounds: int = 2) -> tuple[float, float, float, float]:
    """(runs/s in a plain loop, on local processes, on a Dask LocalCluster, seconds the cluster
    took to start) for the same runs, one after another in this process (a warm-up run loads the
    compiled kernels here first). Local processes and Dask take turns `rounds` times and each
    keeps its fastest round: on a machine shared with other work, the round least disturbed by
    it. The local workers' start (a fork each) is inside their sweep's time; the cluster's
    (processes that import ctsim anew) is printed apart, as it is paid once per cluster, not per
    sweep."""
    _sweep_seconds(Serial(), 1, 0.1)
    loop = runs / _sweep_seconds(Serial(), runs, duration)
    processes, dask, started = 0.0, 0.0, math.inf
    for _ in range(rounds):
        processes = max(processes, runs / _sweep_seconds(Processes(), runs, duration))
        start = time.perf_counter()
        cluster = Dask()
        started = min(started, time.perf_counter() - start)
        dask = max(dask, runs / _sweep_seconds(cluster, runs, duration))
    return loop, processes, dask, started


def _hears_ctrl_c() -> None:
    """SIGINT back to its default in the sweep's process: a bench started in the background by a
    shell without job control ignores SIGINT, and a child inherits that (then it would run on to
    its end, as a background job should, and the figure would time that instead)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def sweep_stop(engine: str = "processes", duration: float = 20.0) -> tuple[float, float]:
    """(seconds from a Ctrl-C to the whole process group of a running `ctsim sweep --engine
    ENGINE` until every process of it is gone, mean wall seconds of one of its runs): a
    terminal's Ctrl-C, as the tests send it, timed here."""
    with tempfile.TemporaryDirectory() as folder:
        spec = Path(folder) / "stop.toml"
        spec.write_text(f"[base]\nduration = {duration}\n[axes]\nseed = {list(range(1000))}\n")
        out = Path(folder) / "out"
        process = subprocess.Popen([sys.executable, "-m", "sim.cli", "sweep", str(spec), "--out", str(out), "--engine", engine],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
                                   preexec_fn=_hears_ctrl_c)  # fmt: skip
        while len(list((out / PARTS).glob("*.parquet"))) < 4:
            time.sleep(0.01)
        start = time.perf_counter()
        os.killpg(process.pid, signal.SIGINT)
        process.wait()
        while True:
            try:
                os.killpg(process.pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.001)
        stopped = time.perf_counter() - start
        return stopped, float(load_results(out)["wall_time_s"].mean())


def vector_env(num_envs: int, steps: int) -> tuple[float, float, float]:
    """(env-steps/s of CtsimVectorEnv with num_envs copies, of one CtsimEnv, and the first per
    second of this process's CPU time) on the line task with its default sensor noise, random
    actions, autoresets included; measured one after the other. The CPU figure is what the wall
    figure would be with a core to itself: on a machine busy with other sessions, the wall figure
    also counts the time this process waits for its turn."""
    from sim.experiments.gym import CtsimEnv, CtsimVectorEnv

    actions = np.random.default_rng(0).uniform(-1, 1, (steps, num_envs, 2)).astype(np.float32)
    vec = CtsimVectorEnv(num_envs, task="line")
    vec.reset(seed=0)
    vec.step(actions[0])
    start, cpu = time.perf_counter(), time.process_time()
    for a in actions:
        vec.step(a)
    batched = steps * num_envs / (time.perf_counter() - start)
    batched_cpu = steps * num_envs / (time.process_time() - cpu)
    env = CtsimEnv("line")
    env.reset(seed=0)
    single = max(20, steps * num_envs // 16)
    start = time.perf_counter()
    for a in actions.reshape(-1, 2)[:single]:
        _, _, terminated, truncated, _ = env.step(a)
        if terminated or truncated:
            env.reset()
    return batched, single / (time.perf_counter() - start), batched_cpu


def figures(scale: float):
    """(name, unit, thunk) for the many-runs benchmarks; each pair is measured together once."""
    cache: dict[str, tuple] = {}

    def once(key, thunk):
        return lambda: cache[key] if key in cache else cache.setdefault(key, thunk())

    sweep_runs = max(10, int(200 * scale))
    measure_sweep = once("sweep", lambda: sweep_engines(sweep_runs))
    yield "sweep_loop", f"runs/s ({sweep_runs} maze runs of 20 s simulated, one after another)", lambda: measure_sweep()[0]
    yield "sweep_processes", "runs/s (the same runs on one warm worker process per core, start-up included)", lambda: measure_sweep()[1]
    yield "sweep_speedup", "x (processes / loop, same run; bar >= 1.7 on two cores)", lambda: measure_sweep()[1] / measure_sweep()[0]
    yield "sweep_dask", "runs/s (the same runs on a started Dask LocalCluster, one worker per core)", lambda: measure_sweep()[2]
    yield "sweep_dask_over_processes", "(Dask / local processes, the faster of two turns each; bar >= 0.9)", lambda: measure_sweep()[2] / measure_sweep()[1]
    yield "sweep_dask_cluster_start", "s (starting that LocalCluster, paid once per cluster)", lambda: measure_sweep()[3]
    measure_dask_stop = once("dask stop", lambda: sweep_stop("dask"))
    yield "sweep_dask_stop_after_sigint", "s (the same on `ctsim sweep --engine dask`: its LocalCluster's workers and scheduler; bar <= 1.5)", lambda: measure_dask_stop()[0]
    measure_stop = once("stop", sweep_stop)
    yield "sweep_stop_after_sigint", "s (Ctrl-C to a running `ctsim sweep`'s process group until all of it is gone; bar <= 2)", lambda: measure_stop()[0]
    yield "sweep_one_run", "s (wall time of one of its runs, for reference)", lambda: measure_stop()[1]
    measure_vec = once("vec", lambda: vector_env(64, max(20, int(300 * scale))))
    yield "gym_vector_64_env_steps_per_s", "env-steps/s (CtsimVectorEnv, 64 copies in one world, line task; bar >= 20,000)", lambda: measure_vec()[0]
    yield "gym_single_env_steps_per_s", "env-steps/s (one CtsimEnv, same task, same run)", lambda: measure_vec()[1]
    yield "gym_vector_64_env_steps_per_cpu_s", "env-steps per CPU second (the 64-copy figure without the wait for a busy machine's cores)", lambda: measure_vec()[2]
