"""summary.json, the one description of a run: written by `ctsim run`, `play` and `bridge`, given
by the Python API (`Result.summary`), read by `ctsim report`, the figures and the HTML pages.

`SCHEMA_VERSION` says which keys it holds; a change of a key's name or meaning raises it.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

import sim
from bots.noise import parse_value
from sim.out_files import open_in_place, write_bytes
from sim.run.samples import RunResult
from sim.world.spec import WorldSpec

SCHEMA_VERSION = 2
"""The version of summary.json's keys (readers may check it; files before it have none). 2: each
estimate's rpe_per_metre (stretches of true path, not evo's) became rpe_translation and
rpe_rotation (`evo_rpe -d 1 -u m`), nees_mean and nees_final are null where the covariance is
degenerate, nees_defined added."""

SUMMARY_ROOM = 16384
"""Bytes held for summary.json from a run's start (and 2 KB more per robot), so that a disk that
fills up during the run (the recording grows) still takes the summary at the end."""


def _world(world: WorldSpec) -> dict[str, str]:
    return {"name": world.name, "source": str(world.source or world.name)}


def goal_note(robot: dict[str, Any]) -> str:
    """A summary robot's goal outcome as summary.json says it ('' in a world without a goal;
    summaries written before it said so: from the goal time)."""
    if robot.get("goal"):
        return robot["goal"]
    return f"goal reached at {robot['goal_time']:.1f} s" if robot["goal_time"] is not None else ""


def summarize(result: RunResult, options: dict[str, Any], metrics: dict[str, dict[str, dict]] | None = None) -> dict[str, Any]:
    """The figures of the table and what produced them, as plain data for summary.json: the run's
    world, seed, step, `options` (what the caller ran it with: duration, robot, noise, ...), how
    it ended, and per robot its distance, collisions, status and each estimate's metrics
    (`metrics`: robot -> estimate -> metrics as a dict, where the caller has them already)."""
    from dataclasses import asdict

    from bots.odometry.defaults import caveats
    from sim.analysis.metrics import compare_run, path_length

    known = caveats()

    if metrics is None:
        metrics = {robot: {name: asdict(m) for name, m in by_name.items()} for robot, by_name in (compare_run(result) if len(result) else {}).items()}
    robots = [
        {
            "name": log.name,
            "robot": log.spec.name,
            "controller": log.controller_name,
            "params": {key: parse_value(value) for key, value in log.params.items()},
            "distance": path_length(result, log),
            "collisions": log.collisions,
            "fell": log.fell,
            "status": "goal reached" if log.goal_time is not None else log.status,
            "goal_time": log.goal_time,
            "goal": log.goal_outcome(result.duration) if result.world.goals else None,
            "estimates": metrics.get(log.name, {}),
            "caveats": {name: known[name] for name in metrics.get(log.name, {}) if name in known},
            "notes": [{"message": message, "steps": count} for message, count in log.notes.values()],
            "puts": [float(log.time_array(slice(k, k + 1))[0]) for k in log.puts],  # (s: the figures break its truth there)
        }
        for log in result.robots
    ]
    return {
        "schema_version": SCHEMA_VERSION,
        "ctsim_version": sim.__version__,
        "world": _world(result.world),
        "seed": result.seed,
        "dt": result.dt,
        **options,
        "time": result.duration,
        "reason": result.reason,
        "error": result.error,
        "robots": robots,
    }


def unstarted(place: WorldSpec, seed: int, dt: float, options: dict[str, Any], reason: str, error: str) -> dict[str, Any]:
    """The summary of a run that has simulated nothing (yet)."""
    return {"schema_version": SCHEMA_VERSION, "ctsim_version": sim.__version__, "world": _world(place),
            "seed": seed, "dt": dt, **options, "time": 0.0, "reason": reason, "error": error, "robots": []}


def json_safe(value: Any) -> Any:
    """Plain JSON: NaN and infinities as null (strict parsers reject them)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    return value


def write_json(path: Path, data: dict[str, Any], reserve: int = 0) -> None:
    """Strict JSON (no NaN). Into the space of an existing file as large as it (so that it fits on
    a disk that has filled up since: `reserve` bytes, padded with whitespace, hold that space),
    else under a temporary name and renamed: whole or absent."""
    text = (json.dumps(json_safe(data), indent=2, allow_nan=False) + "\n").encode()
    text += b" " * (reserve - len(text))
    file = open_in_place(path)  # (a regular file of its own: never through a link)
    if file is not None:
        with file:
            if os.fstat(file.fileno()).st_size >= len(text):
                file.write(text)
                file.truncate()
                return
    write_bytes(path, text)
