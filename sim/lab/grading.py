"""Grading a folder of submissions in parallel: one check per file, then CSV, Gradescope's
results.json and JUnit XML.

Each submission runs in a sandbox of its own (`sim.sandbox`): it sees its own file (or folder)
only, never the other submissions, the seed or the grades. The checks run in threads of this
process (the students' code runs in the sandboxes' processes); the grades are written by this
process alone, after every sandbox has ended with all its processes, into `out`, which no sandbox
can see. A submission that breaks the grader's check is graded as failed with the reason, and the
others are graded all the same.
"""

from __future__ import annotations

import csv
import json
import os
import stat
import sys
import traceback
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from xml.etree import ElementTree as ET

from sim import sanitize
from sim.lab.checking import DEGRADED, CheckReport, Row, check_file, fresh_seed
from sim.lab.exercise import Exercise, ExerciseError
from sim.lab.notebook import SUFFIX, submission
from sim.out_files import kind, replacing, subfolder, write_text
from sim.sandbox import SandboxUnavailable, unavailable


def submissions(folder: Path, name: str, notebooks: bool = False) -> list[Path]:
    """The student files in `folder`: every *.py (and notebook, *.ipynb, if `notebooks`) directly
    in it, whatever it is (a pipe or a link too: `refusal` says why it is not graded), or else one
    per sub-folder (a student each, hidden ones aside): its `name`, else its one notebook, else
    the `name` it lacks (a student who handed in nothing is graded as missing, not left out)."""
    suffixes = (".py", SUFFIX) if notebooks else (".py",)
    found = sorted(p for p in folder.iterdir() if p.suffix in suffixes and not _is_folder(p))
    if found:
        return found
    chosen = []
    for sub in sorted(p for p in folder.iterdir() if p.is_dir() and not p.name.startswith(".")):
        books = sorted(sub.glob(f"*{SUFFIX}")) if notebooks else []
        chosen.append(sub / name if os.path.lexists(sub / name) or len(books) != 1 else books[0])
    return chosen


def others(folder: Path, files: list[Path], out: Path | None = None) -> list[tuple[Path, str]]:
    """Every item of `folder` that is not a submission (`submissions`: `files`), nor the grades
    folder `out`, with why it is not graded: the teacher sees everything a class handed in."""
    own_folders = bool(files) and files[0].parent != folder
    taken = {f.parent if own_folders else f for f in files} | ({Path(out)} if out is not None else set())
    listed = []
    for item in sorted(folder.iterdir()):
        if item in taken or (out is not None and Path(out).resolve() == item.resolve()):
            continue
        kind = "folder" if _is_folder(item) else "file"
        if item.name.startswith("."):
            why = f"a hidden {kind}"
        elif own_folders:
            why = f"a {kind} beside the students' folders (each student's work goes in a folder of its own)"
        elif kind == "folder":
            why = "a folder beside the students' files (a class folder holds either files or one folder per student)"
        else:
            why = f"not a .py file{' or notebook' if any(f.suffix == SUFFIX for f in files) or SUFFIX in item.name else ''}"
        listed.append((item, why))
    return listed


def _is_folder(path: Path) -> bool:
    return stat.S_ISDIR(os.lstat(path).st_mode)


def refusal(path: Path, folder: Path, own_folder: bool, twins: dict[Path, list[str]] | None = None) -> tuple[str, str] | None:
    """Why a submission is not graded, as (problem, message), or None when it is a regular file
    of the student's own: missing, a link (symbolic, or a hard link: its content is another's
    too, `twins` names the classmates sharing it), a pipe, device or folder for a file."""
    if not os.path.lexists(path):
        return "missing", f"no {path.name} (nor one notebook) in the student's folder: nothing to grade"
    if path.is_symlink() or (own_folder and path.parent.is_symlink()) or not path.resolve().is_relative_to(folder):
        return "link", "the submission is a link, not a file of its own: not graded"
    info = os.lstat(path)
    if not stat.S_ISREG(info.st_mode):
        return "not a file", f"the submission is {kind(info.st_mode)}, not a file: not graded"
    if info.st_nlink > 1:
        shared = (twins or {}).get(path, [])
        whose = f"shared with {', '.join(sanitize.name(s, 80) for s in shared)}" if shared else f"one of {info.st_nlink} names of one file"
        return "link", f"the submission is a hard link ({whose}), not a file of its own: not graded"
    return None


def _twins(files: list[Path], ids: list[str]) -> dict[Path, list[str]]:
    """Each file that is one file with others' under several names (hard links): the others' ids."""
    shared: dict[tuple[int, int], list[tuple[Path, str]]] = {}
    for path, sid in zip(files, ids):
        if os.path.lexists(path):
            info = os.lstat(path)
            shared.setdefault((info.st_dev, info.st_ino), []).append((path, sid))
    return {path: [other for _, other in group if other != sid] for group in shared.values() if len(group) > 1 for path, sid in group}


def student_id(path: Path, folder: Path) -> str:
    """The file's stem, or its sub-folder's name for `folder/<student>/<file>` (never a path)."""
    return student_ids([path], folder)[0]


def student_ids(files: list[Path], folder: Path) -> list[str]:
    """Each file's stem, or its sub-folder's name for `folder/<student>/<file>` (never a path);
    the whole file name where two stems are the same (alice.py and alice.ipynb)."""
    stems = [f.parent.name if f.parent != folder else f.stem for f in files]
    ids = [f.name if f.parent == folder and stems.count(stem) > 1 else stem for f, stem in zip(files, stems)]
    return [i if i not in ("", ".", "..") else f"_{i}" for i in ids]


def grade(ex: Exercise, folder: str | Path, out: str | Path, lang: str = "en", seed: int | None = None,
          jobs: int | None = None, degraded: bool = False) -> tuple[list[CheckReport], list[Path]]:  # fmt: skip
    """Check every submission in `folder` against exercise `ex` with `jobs` checks at a time;
    write grades.csv, gradescope/<student>/results.json and junit.xml into `out`. Without
    bubblewrap this refuses (SandboxUnavailable) unless `degraded`, and then says so in every result."""
    folder, out = Path(folder).resolve(), Path(out).resolve()
    files = submissions(folder, ex.file, notebooks=True)
    if not files:
        raise ExerciseError(f"{folder}: no submissions (*.py files or notebooks, or */{ex.file} or one notebook a sub-folder)")
    own_folders = files[0].parent != folder
    if own_folders and any(out.is_relative_to(f.parent) for f in files):
        raise ExerciseError(f"{out}: the grades folder must not be inside a student's folder (the student's code would see it)")
    reason = unavailable()
    if reason is not None and not degraded:
        raise SandboxUnavailable(f"{reason}: refusing to grade untrusted code without isolation (install bubblewrap, or pass --degraded)")
    seed = fresh_seed() if seed is None else seed
    ex.checker  # noqa: B018 (loaded once, before the threads)
    jobs = jobs or max(1, min(len(files), os.cpu_count() or 1))
    ids = student_ids(files, folder)
    twins = _twins(files, ids)
    with ThreadPoolExecutor(jobs) as pool:
        reports = list(pool.map(lambda f: _check(ex, f, folder, lang, seed, own_folders, degraded, twins), files))
    out.mkdir(parents=True, exist_ok=True)
    return reports, [write_csv(out / "grades.csv", ids, reports), write_gradescope(out / "gradescope", ids, reports),
                     write_junit(out / "junit.xml", ids, reports, ex.title["en"])]  # fmt: skip


def _check(ex: Exercise, path: Path, folder: Path, lang: str, seed: int, own_folder: bool, degraded: bool,
           twins: dict[Path, list[str]]) -> CheckReport:  # fmt: skip
    """One submission's report; one not graded (`refusal`), or a failure of the check itself, is a
    failed report with the reason (the grader's own failure is printed, not blamed on the student)."""
    refused = refusal(path, folder, own_folder, twins)
    if refused is not None:
        return _failed(ex, path, seed, *refused)
    try:
        if path.suffix == SUFFIX:
            return _check_notebook(ex, path, lang, seed, degraded)
        return check_file(ex, path, lang, seed, folder=own_folder, degraded=degraded)
    except Exception:  # noqa: BLE001 (a bug of ctsim on one file must not cost the others their grades)
        print(f"ctsim lab grade: checking {sanitize.name(str(path))} failed inside ctsim (a bug, not the student's):\n{traceback.format_exc()}", file=sys.stderr)
        return _failed(ex, path, seed, "grader", "the grader failed on this file (a ctsim bug, not your code): ask your teacher")


def _check_notebook(ex: Exercise, path: Path, lang: str, seed: int, degraded: bool) -> CheckReport:
    """A notebook's report: its solution cell checked as the exercise's file, or, for a notebook
    that is not one of the exercise, a failed report saying why in one line."""
    try:
        with submission(path, ex) as file:
            report = check_file(ex, file, lang, seed, degraded=degraded)
    except ExerciseError as err:
        return _failed(ex, path, seed, "load", str(err).replace(str(path), path.name))
    report.file = str(path)
    return report


def _failed(ex: Exercise, path: Path, seed: int, problem: str, message: str) -> CheckReport:
    return CheckReport(ex.number, str(path), seed, [Row("submission", "", message, "", False, message, problem=problem)], ex.points)


def _isolation(report: CheckReport) -> str:
    return "degraded (no isolation)" if report.degraded else "bubblewrap"


FIELD = 300
"""Characters a text field of the teacher's files keeps (a forged error may be any length)."""


def write_csv(path: Path, ids: list[str], reports: list[CheckReport]) -> Path:
    """One row per student: score (unrounded), maximum, scenarios passed, isolation, the first
    problem and every hidden row's expected and got values (the teacher's file; texts a student
    chose, such as a folder name, never start a formula nor break a line)."""
    with replacing(path, text=True, newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["student", "file", "score", "max_score", "passed", "scenarios", "seed", "isolation", "first_problem", "hidden_values"])
        for sid, report in zip(ids, reports):
            first = next((f"{r.scenario}: {r.values[1]} {r.hint}".strip() for r in report.rows if not r.passed), "")
            hidden = "; ".join(f"{r.scenario}: {'pass' if r.passed else 'FAIL'} expected {r.values[0] or '-'} got {sanitize.truncate(r.values[1], 120)}"
                               for r in report.rows if r.hidden)  # fmt: skip
            writer.writerow([sanitize.csv_cell(sid, FIELD), sanitize.csv_cell(report.file, FIELD), f"{round(report.score, 4):g}", f"{report.points:g}",
                             sum(r.passed for r in report.rows), len(report.rows), report.seed, _isolation(report),
                             sanitize.csv_cell(first, FIELD), sanitize.csv_cell(hidden, 4 * FIELD)])  # fmt: skip
    return path


def feedback(row: Row, teacher: bool = False) -> str:
    """What a student reads about one scenario: expected, got (or the error with its line), the
    tolerance, the hint and what the code printed in it; hidden values stay hidden unless it is
    for the `teacher`."""
    expected, got = row.values if teacher else (row.expected, row.got)
    lines = [f"expected: {expected}"] if expected else []
    lines += [f"got: {sanitize.truncate(got, FIELD)}"] if got else []
    lines += [f"tolerance: {row.tolerance}"] if row.tolerance else []
    lines += [row.hint] if row.hint else []
    lines += [f"Your code printed:\n{row.output}"] if row.output and not teacher else []
    return "\n".join(lines)


def write_gradescope(folder: Path, ids: list[str], reports: list[CheckReport]) -> Path:
    """Gradescope's results.json, one per student in `folder/<student>/results.json` (Gradescope
    grades one submission per container): a test per scenario with its values, error and hint;
    hidden ones (and what the code printed while they ran) show after publishing; the output
    printed while loading and in the public scenarios at the top."""
    for sid, report in zip(ids, reports):
        share = report.points / len(report.rows) if report.rows else 0.0
        tests = [
            {"name": row.scenario, "score": share if row.passed else 0.0, "max_score": share,
             "status": "passed" if row.passed else "failed", "output": sanitize.json_text(feedback(row), 4 * FIELD + 2000),
             "visibility": "after_published" if row.hidden else "visible"}
            for row in report.rows
        ]  # fmt: skip
        notes = ([DEGRADED] if report.degraded else []) + ([f"Your code printed:\n{sanitize.json_text(report.output)}"] if report.output else [])
        results = {"score": round(report.score, 4), "output": "\n\n".join(notes), "tests": tests}
        write_text(subfolder(subfolder(folder) / sid) / "results.json", json.dumps(results, indent=2, ensure_ascii=False) + "\n")
    return folder


def write_junit(path: Path, ids: list[str], reports: list[CheckReport], title: str) -> Path:
    """JUnit XML (the teacher's): a test suite per student, a test case per scenario, failures with
    their hints and values (hidden ones too), what the code printed in each scenario as its
    system-out."""
    suites = ET.Element("testsuites", name=sanitize.xml_text(title))
    for sid, report in zip(ids, reports):
        failures = sum(not r.passed for r in report.rows)
        suite = ET.SubElement(suites, "testsuite", name=sanitize.xml_text(sid), tests=str(len(report.rows)), failures=str(failures))
        properties = ET.SubElement(suite, "properties")
        ET.SubElement(properties, "property", name="isolation", value=_isolation(report))
        for row in report.rows:
            case = ET.SubElement(suite, "testcase", classname=sanitize.xml_text(f"exercise{report.exercise}.{sid}"), name=sanitize.xml_text(row.scenario))
            if not row.passed:
                ET.SubElement(case, "failure", message=sanitize.xml_text(row.hint or "failed", FIELD)).text = sanitize.xml_text(feedback(row, teacher=True))
            if row.output:
                ET.SubElement(case, "system-out").text = sanitize.xml_text(row.output)
    ET.indent(suites)
    with replacing(path) as file:
        ET.ElementTree(suites).write(file, encoding="utf-8", xml_declaration=True)
    return path
