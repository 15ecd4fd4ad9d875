"""Many runs: a small Python API, sweeps on local processes or Dask, and Gymnasium environments.

    from sim.experiments import Bot, simulate, sweep
    result = simulate("maze", Bot("solve_maze"), duration=10)
    table = sweep("spec.toml", "runs/sweep")

The Gymnasium environments live in `sim.experiments.gym` (imported on demand: it registers them).
"""

from sim.experiments.api import (
    Bot,
    Result,
    RobotResult,
    change_robot,
    robot,
    simulate,
    world,
)
from sim.experiments.engines import Dask, Processes, Serial, engine
from sim.experiments.plan import SpecError, SweepSpec, load_sweep, spec_from_dict
from sim.experiments.store import load as load_results
from sim.experiments.sweep import sweep

__all__ = [
    "Bot",
    "Dask",
    "Processes",
    "Result",
    "RobotResult",
    "Serial",
    "SpecError",
    "SweepSpec",
    "change_robot",
    "engine",
    "load_results",
    "load_sweep",
    "robot",
    "simulate",
    "spec_from_dict",
    "sweep",
    "world",
]
