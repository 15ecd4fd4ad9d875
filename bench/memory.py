"""Peak memory and wall time of whole `ctsim run` commands, short against long (issue 17), and the
growth of memory inside one long run (issue 48: the slope, not the start-up's rise).

The growth is a slope over two simulated hours at either scale: a recorded run's RSS rises some
25 MB in its first 10-20 simulated minutes (the first windows of samples, rerun's buffers and
the allocators' free lists settling; 24, 14, 6.5, 4.8, 3.3 and 2.5 MB/h in the six parts of one
2-hour run), in steps of up to 4 MB that a 12-minute run's slope turns into 17-50 MB/h. Without a
recording RSS is flat (0.1 MB in 40 simulated minutes), and Python's objects and the main heap's
blocks in use stay flat with one: what is left after the settling is rerun's (under 1 KB kept
per chunk sent until the file closes, some 1,400 chunks an hour).

Each run is its own process (`/usr/bin/time`-style: `resource.getrusage(RUSAGE_CHILDREN)`), the
default c't-Bot wandering the maze to the time limit (solve_maze's runs end at the goal), recording
on, no figures. The
short run is the reference measured beside the long one: the difference is what the run's length
costs (the run's logs live in a temporary file and leave memory as they are written, so what is left
is the recording's own bookkeeping, about 400 bytes per chunk sent). Whether wall time grows
linearly is read inside the growth's run, from the wall clock sampled with its RSS: the cost per
simulated second of its second half over its first (the start-up before its first sample left out;
single runs of different lengths differed by their start-ups' spread, some 0.5 s, against the
1-2 s their lengths added in --quick, and read -0.003 and 0.62).
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time


def _peak_of_run(duration: float) -> tuple[float, float]:
    """(peak RSS in MB, wall seconds) of `ctsim run maze` for `duration` simulated seconds."""
    with tempfile.TemporaryDirectory() as out:
        script = (
            "import resource, subprocess, sys; "
            f"subprocess.run([sys.executable, '-m', 'sim.cli', 'run', 'maze', '--controller', 'wander', '--duration', '{duration}', '--no-until-goal', "
            f"'--no-report', '--out', '{out}'], stdout=subprocess.DEVNULL, check=True); "
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)"
        )
        start = time.perf_counter()
        done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
        return int(done.stdout.strip()) / 1024, time.perf_counter() - start


_SAMPLED = """
import json, sys, time
from sim.experiments import Bot, simulate


class Sampler:  # RSS (MB, from /proc) and the wall clock against simulated time every `every` samples of the run
    def __init__(self, every):
        self.every, self.count, self.points = every, 0, []

    def on_sample(self, world, logs):
        self.count += 1
        if self.count % self.every == 0:
            with open("/proc/self/statm") as statm:
                self.points.append((world.time, int(statm.read().split()[1]) * 4096 / 2**20, time.perf_counter()))


duration, record = float(sys.argv[1]), sys.argv[2]
sampler = Sampler(1000)
simulate("maze", Bot("wander"), duration=duration, record=record, observers=[sampler])
print(json.dumps(sampler.points))
"""


GROWTH_RUN = 7200.0
"""Simulated seconds of the run whose RSS slope is the growth figure, at either scale (a minute of
CPU): the slope of a one-hour run read 3.5-10.7 MB/h over eight runs, of a two-hour one 2.5-6.1
over four."""


def sampled_run(duration: float) -> dict[str, float]:
    """One run (the main job's world and robot wandering for `duration` s, recording), sampled
    every 10 simulated seconds inside it (Linux's /proc; nan elsewhere): "growth", MB per
    simulated hour by which its resident memory grows after its start-up (the least-squares slope
    of RSS against simulated time over its last four fifths); "linearity", its wall time per
    simulated second in its second half over its first (from its first sample on: 1 is linear)."""
    import json
    import os

    import numpy as np

    with tempfile.TemporaryDirectory() as out:
        done = subprocess.run([sys.executable, "-c", _SAMPLED, str(duration), os.path.join(out, "run.rrd")], capture_output=True, text=True)
    if done.returncode != 0:
        return {"growth": float("nan"), "linearity": float("nan")}
    points = np.array(json.loads(done.stdout.strip().splitlines()[-1]))
    later = points[points[:, 0] >= duration / 5]
    growth = float(np.polyfit(later[:, 0], later[:, 1], 1)[0] * 3600) if len(later) >= 3 else float("nan")
    middle = np.searchsorted(points[:, 0], duration / 2)
    if len(points) < 3 or not 0 < middle < len(points) - 1:
        return {"growth": growth, "linearity": float("nan")}
    (t0, _, w0), (t1, _, w1), (t2, _, w2) = points[0], points[middle], points[-1]
    return {"growth": growth, "linearity": float(((w2 - w1) / (t2 - t1)) / ((w1 - w0) / (t1 - t0)))}


def figures(scale: float):
    """(name, unit, thunk): the long run is 2 simulated hours (12 minutes with --quick), the
    growth's run 2 hours at either scale (`GROWTH_RUN`)."""
    results: dict[str, tuple[float, float]] = {}

    def measure(key: str, duration: float) -> tuple[float, float]:
        if key not in results:
            results[key] = _peak_of_run(duration)
        return results[key]

    long = 7200.0 if scale >= 1 else 720.0
    inside: dict[str, float] = {}

    def sampled(key: str) -> float:
        if not inside:
            inside.update(sampled_run(GROWTH_RUN))
        return inside[key]

    yield "short_run_60s_peak_rss_mb", "MB", lambda: measure("short", 60.0)[0]
    yield "long_run_peak_rss_mb", "MB", lambda: measure("long", long)[0]
    yield ("long_run_rss_growth_mb_per_hour", f"MB per simulated hour (slope of RSS inside one recorded run of {GROWTH_RUN / 3600:g} simulated hours, after its first fifth; bar <= 10)",
           lambda: sampled("growth"))
    yield "long_run_wall_time_ratio", f"x (simulated ratio {long / 60:g})", lambda: measure("long", long)[1] / measure("short", 60.0)[1]
    yield ("long_run_wall_time_linearity", f"(wall time per simulated second, second half / first half of that {GROWTH_RUN / 3600:g}-hour run, from its first sample; 1 = linear)",
           lambda: sampled("linearity"))
