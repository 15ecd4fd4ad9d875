"""What the main job costs: `ctsim run` as a newcomer types it, and a run with a user's own
estimator beside the shipped ones.

`main_job_cpu_s` is the CPU seconds (user and system, the child's own) of `ctsim run` with every
default (a c't-Bot with realistic noise solving the maze, recording, figures and report.html),
after a short run has filled numba's cache: what every run after the first costs.
`own_estimator_cost` is the wall time of a run with one small Python estimator (`Ticks` below)
over the same run without it: the shipped estimators stay in their compiled pass beside it.
"""

from __future__ import annotations

import math
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _cpu_of(arguments: list[str]) -> float:
    """CPU seconds (user + system) of `ctsim ARGUMENTS` in a child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run([sys.executable, "-m", "sim.cli", *arguments], cwd=ROOT, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main_job_cpu_s() -> float:
    """CPU seconds of the warm main job (`ctsim run`, every default) in its own process."""
    with tempfile.TemporaryDirectory() as out:
        _cpu_of(["run", "--duration", "1", "--no-report", "--out", f"{out}/warm"])
        return _cpu_of(["run", "--out", f"{out}/main"])


class Ticks:
    """A user's estimator as small as one gets: dead reckoning from the encoder ticks in Python,
    unpacked with `.tolist()` as `Readings` advises (its items as numpy int64 scalars cost it some
    2 µs a step of numpy scalar arithmetic, its own cost, not the run's)."""

    name = "ticks"

    def reset(self, robot, pose) -> None:  # noqa: ANN001 (a RobotSpec, a pose)
        self.metres_per_tick = math.pi * robot.wheel_diameter / robot.encoders.ticks_per_rev
        self.track = robot.track_width
        self.pose = [float(pose[0]), float(pose[1]), float(pose[2])]

    def update(self, readings) -> None:  # noqa: ANN001 (Readings)
        left, right = readings.encoder_ticks.tolist()
        sl, sr = left * self.metres_per_tick, right * self.metres_per_tick
        x, y, heading = self.pose
        middle = heading + (sr - sl) / (2 * self.track)
        self.pose = [x + 0.5 * (sl + sr) * math.cos(middle), y + 0.5 * (sl + sr) * math.sin(middle), heading + (sr - sl) / self.track]


def own_estimator_cost(duration: float, rounds: int = 3) -> float:
    """Wall time of the main job's run (no recording) with `Ticks` beside the shipped estimators
    over the same run without it, best of `rounds` alternating runs of each."""
    from sim.experiments import Bot, simulate

    best = {False: math.inf, True: math.inf}
    for _ in range(rounds):
        for own in best:
            started = time.perf_counter()
            simulate("maze", Bot("solve_maze"), duration=duration, estimators=[Ticks] if own else ())
            best[own] = min(best[own], time.perf_counter() - started)
    return best[True] / best[False]


def figures(scale: float):
    """(name, unit, thunk) of the main job's costs."""
    yield "main_job_cpu_s", "s of CPU (warm `ctsim run`, every default: realistic noise, solve_maze in the maze, recording, report)", main_job_cpu_s
    yield "own_estimator_cost", "(a run with one user estimator / without, best of alternating runs; bar <= 1.2)", lambda: own_estimator_cost(max(300.0 * scale, 60.0))
