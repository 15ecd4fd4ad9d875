"""Grading a folder of submissions in parallel: one check per file, then CSV, Gradescope's
results.json and JUnit XML.

Each submission is checked in a process of the pool (which starts the student's own process in
turn); every submission meets the same hidden scenarios, drawn from the grading's seed.
"""

from __future__ import annotations

import csv
import json
import os
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path
from xml.etree import ElementTree as ET

from sim.lab.checking import CheckReport, check_file, fresh_seed
from sim.lab.exercise import exercise


def _check(args: tuple) -> CheckReport:
    number, path, lang, seed, extra = args
    return check_file(exercise(number, extra), path, lang, seed)


def submissions(folder: Path, name: str) -> list[Path]:
    """The student files in `folder`: every *.py directly in it, or `name` in each sub-folder."""
    found = sorted(p for p in folder.glob("*.py") if p.is_file())
    return found or sorted(p for p in folder.glob(f"*/{name}") if p.is_file())


def student_id(path: Path, folder: Path) -> str:
    """The file's stem, or its sub-folder's name for `folder/<student>/<file>`."""
    return path.parent.name if path.parent != folder else path.stem


def grade(number: int, folder: str | Path, out: str | Path, lang: str = "en", seed: int | None = None,
          jobs: int | None = None, extra: list | None = None) -> tuple[list[CheckReport], list[Path]]:
    """Check every submission in `folder` against exercise `number` with `jobs` processes;
    write grades.csv, gradescope/<student>/results.json and junit.xml into `out`."""
    folder, out = Path(folder), Path(out)
    ex = exercise(number, extra)
    files = submissions(folder, ex.file)
    if not files:
        raise ValueError(f"{folder}: no submissions (*.py files, or */{ex.file})")
    seed = fresh_seed() if seed is None else seed
    jobs = jobs or max(1, min(len(files), os.cpu_count() or 1))
    with ProcessPoolExecutor(jobs, mp_context=get_context("spawn")) as pool:
        reports = list(pool.map(_check, [(number, f, lang, seed, extra) for f in files]))
    out.mkdir(parents=True, exist_ok=True)
    ids = [student_id(f, folder) for f in files]
    return reports, [write_csv(out / "grades.csv", ids, reports), write_gradescope(out / "gradescope", ids, reports),
                     write_junit(out / "junit.xml", ids, reports, ex.title["en"])]  # fmt: skip


def write_csv(path: Path, ids: list[str], reports: list[CheckReport]) -> Path:
    """One row per student: score, maximum, scenarios passed, and the first hint."""
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.writer(f)
        writer.writerow(["student", "file", "score", "max_score", "passed", "scenarios", "seed", "first_problem"])
        for sid, report in zip(ids, reports):
            first = next((f"{r.scenario}: {r.got if not r.hidden else ''} {r.hint}".strip() for r in report.rows if not r.passed), "")
            writer.writerow([sid, report.file, f"{report.score:.2f}", f"{report.points:g}", sum(r.passed for r in report.rows), len(report.rows), report.seed, first])
    return path


def write_gradescope(folder: Path, ids: list[str], reports: list[CheckReport]) -> Path:
    """Gradescope's results.json, one per student in `folder/<student>/results.json` (Gradescope
    grades one submission per container): a test per scenario; hidden ones show after publishing."""
    for sid, report in zip(ids, reports):
        share = report.points / len(report.rows) if report.rows else 0.0
        tests = [
            {"name": row.scenario, "score": share if row.passed else 0.0, "max_score": share,
             "status": "passed" if row.passed else "failed", "output": row.hint,
             "visibility": "after_published" if row.hidden else "visible"}
            for row in report.rows
        ]  # fmt: skip
        target = folder / sid / "results.json"
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(json.dumps({"score": round(report.score, 4), "tests": tests}, indent=2, ensure_ascii=False) + "\n", encoding="utf-8")
    return folder


def write_junit(path: Path, ids: list[str], reports: list[CheckReport], title: str) -> Path:
    """JUnit XML: a test suite per student, a test case per scenario, failures with their hints."""
    suites = ET.Element("testsuites", name=title)
    for sid, report in zip(ids, reports):
        failures = sum(not r.passed for r in report.rows)
        suite = ET.SubElement(suites, "testsuite", name=sid, tests=str(len(report.rows)), failures=str(failures))
        for row in report.rows:
            case = ET.SubElement(suite, "testcase", classname=f"exercise{report.exercise}.{sid}", name=row.scenario)
            if not row.passed:
                ET.SubElement(case, "failure", message=row.hint or "failed").text = row.got
    ET.indent(suites)
    ET.ElementTree(suites).write(path, encoding="utf-8", xml_declaration=True)
    return path
