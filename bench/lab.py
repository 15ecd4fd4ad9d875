"""Lab benchmark: `ctsim lab grade` over 30 generated submissions of exercise 2 and one submission
checked alone (bars: 2 s and 20 s on two cores), beside what they are made of, measured in the same
run: a bare interpreter's start and one sandboxed guest's whole life; and a class of 100
submissions of exercise 3 beside 100 of exercise 2 (wall time, the grader's peak memory and the
largest guest's), each graded in a process of its own so that its peak is its own.

    python bench/lab.py            # the class figures only (minutes: 100 sandboxes each)
    python bench/run.py -k lab     # all of them
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
KINDS = ("reference", "euler", "old_heading", "degrees", "swapped", "straight")
CLASS = 100
"""Submissions of a class graded for the class figures."""
GRADE_CLASS = """
import json, resource, sys, time
from pathlib import Path
from sim.lab import exercise
from sim.lab.grading import grade
folder, out, number = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
start = time.perf_counter()
reports, _ = grade(exercise(number), folder, out, seed=1)
seconds = time.perf_counter() - start
print(json.dumps({"seconds": seconds, "grader_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "guest_mb": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024, "graded": len(reports)}))
"""
"""A grading of one class in a fresh interpreter: wall time (s), peak resident memory of the
grader and of its largest child (a guest, MB), as JSON."""


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


def grade_class(number: int, count: int = CLASS) -> dict[str, float]:
    """Grade `count` submissions of exercise `number` (its reference and typical wrong solutions
    from tests/lab, in turn) in a process of its own: its GRADE_CLASS figures."""
    sources = sorted((ROOT / "tests" / "lab" / f"ex{number}").glob("*.py"))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "subs"
        folder.mkdir()
        for i in range(count):
            (folder / f"student{i:03d}.py").write_text(sources[i % len(sources)].read_text())
        result = subprocess.run([sys.executable, "-c", GRADE_CLASS, str(folder), str(Path(tmp) / "out"), str(number)],
                                capture_output=True, text=True, check=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)})  # fmt: skip
        return json.loads(result.stdout.splitlines()[-1])


def class_figures():
    """Exercise 3's class beside exercise 2's: wall time and peak memory, each graded once."""
    found = {}

    def figure(number: int, key: str):
        def value() -> float:
            if number not in found:
                found[number] = grade_class(number)
            return found[number][key]

        return value

    for number in (2, 3):
        yield f"lab_grade_{CLASS}_ex{number}", f"s (exercise {number}, {CLASS} submissions, a CPU each at a time)", figure(number, "seconds")
        yield f"lab_grade_{CLASS}_ex{number}_grader_peak", "MB (the grading process's peak resident memory)", figure(number, "grader_mb")
        yield f"lab_grade_{CLASS}_ex{number}_guest_peak", "MB (the largest guest's peak resident memory)", figure(number, "guest_mb")


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
        yield from class_figures()


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT))
    for name, unit, measure in class_figures():
        print(f"{name}: {measure():.3g} {unit}", flush=True)
