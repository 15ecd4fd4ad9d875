"""Lab benchmark: `ctsim lab grade` over 30 generated submissions of exercise 2 and one submission
checked alone (bars: 2 s and 20 s on two cores), beside what they are made of, measured in the same
run: a bare interpreter's start and one sandboxed guest's whole life."""

from __future__ import annotations

import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
KINDS = ("reference", "euler", "old_heading", "degrees", "swapped", "straight")


def best(thunk, repeats: int = 5) -> float:
    """The fastest of `repeats` timings of `thunk` (s): the machine is shared."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        thunk()
        times.append(time.perf_counter() - start)
    return min(times)


def python_start() -> float:
    """Seconds for `python -I -S -c pass`: the reference the others are made of."""
    return best(lambda: subprocess.run([sys.executable, "-I", "-S", "-c", "pass"], check=True))


def sandbox_life() -> float:
    """Seconds for one sandboxed guest: started, a file loaded, one call answered, every process gone."""
    from sim.sandbox import Sandbox

    with tempfile.TemporaryDirectory() as tmp:
        code = Path(tmp) / "code.py"
        code.write_text("def f(x):\n    return 2 * x\n")

        def life() -> None:
            with Sandbox(code) as box:
                box.call("f", 1.0, timeout=60.0)

        return best(life)


def grade_30(count: int = 30, number: int = 2) -> tuple[float, float]:
    """(seconds to grade `count` submissions of exercise `number` in parallel, seconds to check one alone)."""
    from sim.lab import check_file, exercise
    from sim.lab.grading import grade

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "subs"
        folder.mkdir()
        for i in range(count):
            kind = KINDS[i % len(KINDS)] if number == 2 else "reference"
            (folder / f"student{i:02d}.py").write_text((ROOT / "tests" / "lab" / f"ex{number}" / f"{kind}.py").read_text())
        start = time.perf_counter()
        check_file(exercise(number), folder / "student00.py", seed=1)
        single = time.perf_counter() - start
        if count == 1:
            return single, single
        start = time.perf_counter()
        grade(exercise(number), folder, Path(tmp) / "out", seed=1)
        return time.perf_counter() - start, single


def figures(scale: float):
    results = {}

    def total() -> float:
        results["grade"], results["one"] = grade_30()
        return results["grade"]

    yield "lab_python_start", "s (reference: a bare interpreter's start, this run)", python_start
    yield "lab_sandbox_life", "s (one guest in bubblewrap: start, load, one call, all processes gone)", sandbox_life
    yield "lab_grade_30_submissions", "s (exercise 2, 11 scenarios each; bar < 20 s)", total
    yield "lab_check_1_submission", "s (exercise 2 alone; bar < 2 s)", lambda: results["one"]
    if scale >= 1.0:
        yield "lab_check_1_submission_ex3", "s (exercise 3: four runs of 7-12 s simulated, the estimator fed each in one request)", lambda: grade_30(1, 3)[1]
