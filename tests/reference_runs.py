"""Reference runs for issue 16's speed work: noise-free scenarios whose trajectories and readings
were stored (tests/data/reference_runs.npz) before the hot paths were rewritten, so that
`test_reference_runs.py` can show the faster code computes the same thing.

    python -m tests.reference_runs     # rewrite the stored file (only for an intended model change)
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bots.behaviours import make
from bots.ctbot import CTBOT
from bots.spec import BeliefSpec
from sim.run.loop import RobotSetup, run
from sim.world import World
from sim.world.files import load_world
from tests.observers import KeepReadings

STORE = Path(__file__).resolve().parent / "data" / "reference_runs.npz"
BARE = CTBOT.with_changes(name="bare", mouse=None, ir=(), line=(), border=(), light=())
EXACT = CTBOT.with_changes(belief=BeliefSpec(0.0, 0.0, 0.0, 0.0, 0.0, 0.0))
"""The c't-Bot told it is exact, as every noise-free robot's estimators believed when the runs were
stored (the fused filter's calibration then stays put)."""
READING_FIELDS = ("encoder_ticks", "mouse_counts", "ir_raw", "ir_distance", "line", "border", "light")


def maze_solve(steps: int = 1500) -> dict[str, np.ndarray]:
    """`sim.run.loop.run` of a c't-Bot solving the maze: truth, the four estimates, every reading."""
    keep = KeepReadings()
    result = run(load_world("maze"), [RobotSetup(EXACT, make("solve_maze", {}))], steps * 0.01, observers=[keep])
    log = result.robots[0]
    out = {"maze_solve/time": result.time, "maze_solve/truth": log.truth_array()}
    out |= {f"maze_solve/estimate/{k}": v for k, v in log.estimate_arrays().items()}
    out |= {f"maze_solve/{f}": np.array([getattr(r, f) for r in keep.readings]) for f in READING_FIELDS}
    return {k: np.array(v) for k, v in out.items()}


def crowd(count: int = 40, steps: int = 400) -> dict[str, np.ndarray]:
    """`count` bare robots (no IR: independent of the IR model) packed in a 1 m square of the
    empty world, driving fixed arcs towards and into each other: robot-robot cuts every step."""
    world = World(load_world("empty"))
    rng = np.random.default_rng(16)
    side = int(np.ceil(np.sqrt(count)))
    for k in range(count):
        x, y = -0.5 + 0.14 * (k % side), -0.5 + 0.14 * (k // side)
        world.add_robot(BARE, (x, y, float(rng.uniform(-np.pi, np.pi))))
    commands = rng.uniform(-80.0, 255.0, size=(count, 2))
    poses = np.empty((steps + 1, count, 3))
    poses[0] = world.poses()
    for k in range(steps):
        world.step(commands)
        poses[k + 1] = world.poses()
    return {"crowd/poses": poses}


def scenarios() -> dict[str, np.ndarray]:
    return maze_solve() | crowd()


if __name__ == "__main__":
    np.savez_compressed(STORE, **scenarios())
    print(f"wrote {STORE}")
