"""Many runs: a small Python API, sweeps on local processes or Dask, and Gymnasium environments.

    from sim.experiments import Bot, simulate, sweep
    result = simulate("maze", Bot("solve_maze"), duration=10)
    table = sweep("spec.toml", "runs/sweep")

The Gymnasium environments live in `sim.experiments.gym` (imported on demand: it registers them).
The sweep's names load on first use: they bring pandas and pyarrow (80 MB), which a single run
(`ctsim run`, `simulate`) does not need.
"""

from importlib import import_module

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

_ON_DEMAND = {"sweep": ("sim.experiments.sweeping", "sweep"), "load_results": ("sim.experiments.store", "load"), "summary_table": ("sim.experiments.report", "summary_table")}


def __getattr__(name: str):
    """`sweep`, `load_results` and `summary_table` (the runs grouped: means, NEES over the runs with its interval), imported when first asked for (PEP 562)."""
    if name not in _ON_DEMAND:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module, attribute = _ON_DEMAND[name]
    value = getattr(import_module(module), attribute)
    globals()[name] = value
    return value


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
    "summary_table",
    "sweep",
    "world",
]
