"""Many-runs benchmarks: a sweep on local processes against a plain loop of the same runs, and the
vectorised Gymnasium environment against N separate environments."""

from __future__ import annotations

import tempfile
import time

import numpy as np

from sim.experiments import Processes, Serial, sweep


def _sweep_seconds(runner, runs: int, duration: float) -> float:
    spec = {"base": {"duration": duration}, "axes": {"seed": list(range(runs))}}
    with tempfile.TemporaryDirectory() as folder:
        start = time.perf_counter()
        sweep(spec, folder, runner, progress=False)
        return time.perf_counter() - start


def sweep_speedup(runs: int, duration: float = 2.0) -> tuple[float, float, float]:
    """(runs/s on local processes, runs/s in a plain loop, their ratio) for the same runs, worker
    start-up included (a warm-up run loads the compiled kernels first)."""
    _sweep_seconds(Serial(), 1, 0.1)
    loop = runs / _sweep_seconds(Serial(), runs, duration)
    processes = runs / _sweep_seconds(Processes(), runs, duration)
    return processes, loop, processes / loop


def vector_env(num_envs: int, steps: int) -> tuple[float, float]:
    """(env-steps/s of CtsimVectorEnv with num_envs copies, of num_envs separate CtsimEnvs)."""
    from sim.experiments.gym import CtsimEnv, CtsimVectorEnv

    actions = np.random.default_rng(0).uniform(-1, 1, (steps, num_envs, 2)).astype(np.float32)
    vec = CtsimVectorEnv(num_envs, task="line")
    vec.reset(seed=0)
    start = time.perf_counter()
    for a in actions:
        vec.step(a)
    batched = steps * num_envs / (time.perf_counter() - start)
    envs = [CtsimEnv("line") for _ in range(num_envs)]
    for i, env in enumerate(envs):
        env.reset(seed=i)
    start = time.perf_counter()
    for a in actions:
        for env, action in zip(envs, a):
            _, _, terminated, truncated, _ = env.step(action)
            if terminated or truncated:
                env.reset()
    return batched, steps * num_envs / (time.perf_counter() - start)


def figures(scale: float):
    """(name, unit, thunk) for the many-runs benchmarks; each pair is measured together once."""
    cache: dict[str, tuple] = {}

    def once(key, thunk):
        return lambda: cache.setdefault(key, thunk())

    sweep_runs = max(4, int(40 * scale))
    measure_sweep = once("sweep", lambda: sweep_speedup(sweep_runs))
    yield "sweep_processes", "runs/s", lambda: measure_sweep()[0]
    yield "sweep_loop", "runs/s", lambda: measure_sweep()[1]
    yield "sweep_speedup", "x", lambda: measure_sweep()[2]
    measure_vec = once("vec", lambda: vector_env(8, max(20, int(200 * scale))))
    yield "gym_vector_8_envs", "env-steps/s", lambda: measure_vec()[0]
    yield "gym_8_separate_envs", "env-steps/s", lambda: measure_vec()[1]
