"""Lab benchmark: `ctsim lab grade` over 30 generated submissions of exercise 2, beside one
submission checked alone in the same run."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
KINDS = ("reference", "euler", "old_heading", "degrees", "swapped", "straight")


def grade_30(count: int = 30) -> tuple[float, float]:
    """(seconds to grade `count` submissions in parallel, seconds to check one alone)."""
    from sim.lab import check_file, exercise
    from sim.lab.grading import grade

    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp) / "subs"
        folder.mkdir()
        for i in range(count):
            kind = KINDS[i % len(KINDS)]
            (folder / f"student{i:02d}.py").write_text((ROOT / "tests" / "lab" / "ex2" / f"{kind}.py").read_text())
        start = time.perf_counter()
        check_file(exercise(2), folder / "student00.py", seed=1)
        single = time.perf_counter() - start
        start = time.perf_counter()
        grade(exercise(2), folder, Path(tmp) / "out", seed=1)
        return time.perf_counter() - start, single


def figures(scale: float):
    results = {}

    def total() -> float:
        results["grade"], results["one"] = grade_30()
        return results["grade"]

    yield "lab_grade_30_submissions", "s", total
    yield "lab_check_1_submission", "s", lambda: results["one"]
