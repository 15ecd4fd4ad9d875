"""A sweep's plan: the TOML spec, checked, and expanded into runs that each carry all their settings.

    [sweep]
    mode = "grid"                  # every combination of [axes]; "random": `samples` draws
    [base]                         # the same in every run
    world = "maze"
    duration = 2.0
    [axes]                         # what varies
    seed = [0, 1, 2, 3, 4]
    "robot.encoders.slip_std" = [0.0, 0.01, 0.02, 0.05]
    "params.speed" = { uniform = [0.1, 0.3] }     # random mode only
    noise = ["none", "realistic", "harsh"]        # or one preset in [base] (default: realistic)

Settings: world, controller, robot, noise, seed, duration, dt, until_goal; `params.NAME` for a controller
parameter; `robot.FIELD[.FIELD]` for a robot field (`sim.experiments.api.change_robot`). A run's
id is a hash of its settings, so a run is the same run whatever the engine, order or restart.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bots.noise import DEFAULT_NOISE, NOISE_PRESETS
from bots.schema import Field, Problem
from bots.spec import read_toml
from sim.errors import UserError
from sim.run.loop import MAX_DURATION
from sim.world.step import DEFAULT_DT, DT_RANGE

DEFAULTS: dict[str, Any] = {
    "world": "maze",
    "controller": "solve_maze",
    "robot": "ctbot",
    "noise": DEFAULT_NOISE,
    "seed": 0,
    "duration": 10.0,
    "dt": DEFAULT_DT,
    "until_goal": False,
}
"""Every run's settings start from these."""
DISTRIBUTIONS = ("uniform", "log_uniform", "integers")
"""Random-mode draws: `{uniform = [lo, hi]}`, `{log_uniform = [lo, hi]}`, `{integers = [lo, hi]}`
(both ends included); a list draws one of its values."""
ARTEFACTS = ("tum", "recording")
MAX_RUNS = 100_000
"""Most runs one sweep plans: its plan is expanded in memory before the first run (about 1 KB a run)."""


SEED = Field("integer", "", 0, 2**63 - 1)
SETTINGS: dict[str, Field] = {
    "world": Field("text"), "controller": Field("text"), "robot": Field("text"), "noise": Field("text", choices=tuple(NOISE_PRESETS)), "seed": SEED,
    "duration": Field("number", "s", 0.0, MAX_DURATION), "dt": Field("number", "s", *DT_RANGE), "until_goal": Field("boolean"),
}
"""Every run setting but `params.NAME` and `robot.FIELD` (checked by the controller and the robot's own
schema); `noise` is the preset applied before `robot.FIELD` changes, as `--noise` before `--robot-set`."""
OPTIONS: dict[str, Field] = {
    "mode": Field("text", choices=("grid", "random"), default="grid"), "samples": Field("integer", "runs", 1, MAX_RUNS, default=0),
    "seed": Field("integer", "", 0, 2**63 - 1, default=0), "artefacts": Field("texts", choices=ARTEFACTS, default=()),
}
"""The `[sweep]` table."""


class SpecError(UserError):
    """A mistake in a sweep spec; the message names the file and the key."""


@dataclass(frozen=True)
class SweepSpec:
    """A checked sweep: constant settings, swept axes, how to combine them, what to keep per run."""

    base: dict[str, Any]
    axes: dict[str, Any]
    mode: str = "grid"
    samples: int = 0
    seed: int = 0
    artefacts: tuple[str, ...] = ()
    source: str = "<sweep>"


@dataclass(frozen=True)
class Job:
    """One run of a sweep: its position in the plan, its id and every setting it needs."""

    index: int
    run_id: str
    settings: dict[str, Any] = field(hash=False)
    keep: tuple[str, ...] = ()
    """Artefacts to write (`ARTEFACTS`) into `folder`."""
    folder: str | None = None
    estimators: tuple[str, ...] = ()
    """Estimators to run beside the shipped ones (`bots.odometry.user.load`'s sources: `ctsim evaluate`)."""
    step_timeout: float | None = None
    """Seconds (wall clock) a call of the user's code may take (`sim.run.clock.StepClock`; None: no
    limit). Not part of the run's id: a run that finishes is the same run under any limit."""
    isolate: bool = False
    """`estimators`' files run in processes of their own, isolated by the operating system
    (`sim.sandbox.isolated`; needs a `step_timeout`). Not part of the run's id, as the limit."""


def _check_key(key: str, where: str) -> None:
    head, dot, rest = key.partition(".")
    if key in DEFAULTS or (dot and rest and head in ("params", "robot")):
        return
    raise SpecError(f"{where}: unknown setting {key!r} (known: {', '.join(DEFAULTS)}, params.NAME, robot.FIELD)")


def _check_value(key: str, value: Any, where: str) -> None:
    """A setting's value against its Field (SETTINGS)."""
    if key in SETTINGS:
        try:
            SETTINGS[key].check(value)
        except Problem as problem:
            raise SpecError(f"{where}: {key}: {problem.message}") from None


def _check_axis(key: str, values: Any, mode: str, where: str) -> None:
    if isinstance(values, list):
        if not values:
            raise SpecError(f"{where}: axis {key!r} has no values")
        for value in values:
            _check_value(key, value, where)
        return
    if isinstance(values, dict) and mode == "random" and len(values) == 1 and next(iter(values)) in DISTRIBUTIONS:
        (kind, bounds), = values.items()
        if not (isinstance(bounds, list) and len(bounds) == 2 and all(isinstance(b, (int, float)) for b in bounds) and bounds[0] <= bounds[1]):
            raise SpecError(f"{where}: axis {key!r}: {kind} needs [low, high] with low <= high, got {bounds!r}")
        if kind == "log_uniform" and bounds[0] <= 0:
            raise SpecError(f"{where}: axis {key!r}: log_uniform needs positive bounds, got {bounds!r}")
        return
    hint = f" or one of {{{', '.join(d + ' = [lo, hi]' for d in DISTRIBUTIONS)}}}" if mode == "random" else " (distributions need mode = \"random\")"
    raise SpecError(f"{where}: axis {key!r} must be a list of values{hint}, got {values!r}")


def spec_from_dict(data: dict[str, Any], source: str = "<sweep>") -> SweepSpec:
    """Check plain data (as read from TOML) and build a SweepSpec; SpecError names the key."""
    unknown = sorted(set(data) - {"sweep", "base", "axes"})
    if unknown:
        raise SpecError(f"{source}: unknown table(s) {', '.join(unknown)} (expected [sweep], [base], [axes])")
    for table in ("sweep", "base", "axes"):
        if not isinstance(data.get(table, {}), dict):
            raise SpecError(f"{source}: [{table}] must be a table")
    options = dict(data.get("sweep", {}))
    unknown = sorted(set(options) - set(OPTIONS))
    if unknown:
        raise SpecError(f"{source}: [sweep]: unknown key(s) {', '.join(unknown)} (known: {', '.join(OPTIONS)})")
    chosen = {}
    for key, spec in OPTIONS.items():
        try:
            chosen[key] = spec.check(options[key]) if key in options else spec.default
        except Problem as problem:
            raise SpecError(f"{source}: [sweep] {key}: {problem.message}") from None
    mode, samples, seed, artefacts = chosen.values()
    if mode == "random" and not samples:
        raise SpecError(f"{source}: [sweep] mode = \"random\" needs samples = a positive integer")
    base, axes = dict(data.get("base", {})), dict(data.get("axes", {}))
    for key in base:
        _check_key(key, f"{source}: [base]")
        _check_value(key, base[key], f"{source}: [base]")
    for key, values in axes.items():
        _check_key(key, f"{source}: [axes]")
        _check_axis(key, values, mode, f"{source}: [axes]")
    count = samples if mode == "random" else math.prod(len(values) for values in axes.values())
    if count > MAX_RUNS:
        raise SpecError(f"{source}: the plan has {count:,} runs, more than the {MAX_RUNS:,} one sweep holds; split it into several sweeps")
    both = sorted(set(base) & set(axes))
    if both:
        raise SpecError(f"{source}: {', '.join(both)} in both [base] and [axes]; keep one")
    return SweepSpec(base, axes, mode, samples, seed, tuple(artefacts), source)


def load_sweep(path: str | Path) -> SweepSpec:
    """Read and check a sweep spec from a TOML file."""
    return spec_from_dict(read_toml(Path(path), SpecError), str(path))


def _draw(values: Any, rng: np.random.Generator) -> Any:
    if isinstance(values, list):
        return values[int(rng.integers(len(values)))]
    (kind, (low, high)), = values.items()
    if kind == "uniform":
        return float(rng.uniform(low, high))
    if kind == "log_uniform":
        return float(math.exp(rng.uniform(math.log(low), math.log(high))))
    return int(rng.integers(int(low), int(high), endpoint=True))


def settings(spec: SweepSpec) -> list[dict[str, Any]]:
    """Every run's full settings in plan order: the grid's combinations (last axis fastest) or
    `samples` draws, draw i from its own generator spawned from the sweep's seed (so that more
    samples keep the first ones)."""
    fixed = {**DEFAULTS, **spec.base}
    names = list(spec.axes)
    if spec.mode == "grid":
        combos = itertools.product(*(spec.axes[n] for n in names))
        return [{**fixed, **dict(zip(names, combo))} for combo in combos]
    rngs = [np.random.default_rng(s) for s in np.random.SeedSequence(spec.seed).spawn(spec.samples)]
    return [{**fixed, **{n: _draw(spec.axes[n], rng) for n in names}} for rng in rngs]


def run_id(values: dict[str, Any]) -> str:
    """A short stable hash of a run's settings (key order does not matter)."""
    text = json.dumps(values, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def jobs(spec: SweepSpec, out: Path | None = None) -> list[Job]:
    """The plan's runs, each once (a combination drawn or listed twice is one run); with `out`
    and artefacts asked for, each keeps them in `out/runs/<run_id>/`."""
    planned: dict[str, Job] = {}
    for index, values in enumerate(settings(spec)):
        rid = run_id(values)
        if rid not in planned:
            keep = spec.artefacts if out is not None else ()
            planned[rid] = Job(index, rid, values, keep, str(out / "runs" / rid) if keep else None)
    return list(planned.values())
