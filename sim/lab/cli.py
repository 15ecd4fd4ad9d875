"""`ctsim lab list|start|check|grade`: thin handlers over the package, called by sim/cli/lab.py."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from sim import sanitize
from sim.folder_lock import held
from sim.lab.checking import DEGRADED, check_and_print
from sim.lab.exercise import Exercise, ExerciseError, exercise, exercises
from sim.lab.grading import grade, others, submissions
from sim.lab.notebook import submission, write_notebook
from sim.out_files import write_text
from sim.sandbox import SandboxUnavailable


def lab_command(args: argparse.Namespace) -> int:
    """Run one lab action; 0 done (or the file passed), 1 the file fails (or the grader failed on
    a submission), user errors (and a machine without bubblewrap, unless --degraded) raise."""
    extra = args.exercises
    if args.lab_command == "list":
        for number, ex in exercises(extra).items():
            print(f"{number:>3}  {ex.title[args.lang]}: {ex.summary[args.lang]}")
        return 0
    ex = exercise(args.number, extra)
    if args.lab_command == "start":
        if args.notebook:
            return _start_notebook(ex, args.dir, args.lang, extra)
        return _start(ex, args.dir, args.lang)
    try:
        return _check(ex, args) if args.lab_command == "check" else _grade(ex, args)
    except SandboxUnavailable as err:
        raise ExerciseError(str(err)) from None


def _check(ex: Exercise, args: argparse.Namespace) -> int:
    if not args.file.is_file():
        raise ExerciseError(f"{args.file}: no such file")
    with submission(args.file, ex) as file:  # a notebook: its solution cell, as the file
        return 0 if check_and_print(ex, file, args.file, args.lang, args.out, args.degraded).passed else 1


def _grade(ex: Exercise, args: argparse.Namespace) -> int:
    """0 when every submission was graded; 1 when the grader failed on one (printed, a ctsim bug)."""
    if not args.submissions.is_dir():
        raise ExerciseError(f"{args.submissions}: no such folder")
    out = args.out or args.submissions / "grades"
    with held(out, "lab grade"):  # (two gradings into one folder would interleave their tables)
        reports, written = grade(ex, args.submissions, out, args.lang, args.seed, args.jobs, args.degraded)
    if any(r.degraded for r in reports):
        print(DEGRADED)
    for report in reports:
        print(f"{report.score_text:>7}  {sanitize.name(report.file)}")
    folder = args.submissions.resolve()
    for item, why in others(folder, submissions(folder, ex.file, notebooks=True), out):
        print(f"{'-':>7}  {sanitize.name(str(item))}: not graded: {why}")
    print(f"{sum(r.passed for r in reports)}/{len(reports)} passed; scenario seed {reports[0].seed}")
    for path in written:
        print(f"  wrote {sanitize.name(str(path))}")
    return 1 if any(row.problem == "grader" for r in reports for row in r.rows) else 0


def _start(ex, folder: Path, lang: str) -> int:
    folder.mkdir(parents=True, exist_ok=True)
    sheet, template = folder / f"exercise{ex.number}.md", folder / ex.file
    write_text(sheet, ex.sheet(lang))
    if os.path.lexists(template):
        print(f"kept {sanitize.name(str(template))} (it exists; delete it for a fresh template)")
    else:
        write_text(template, ex.template())
        print(f"wrote {sanitize.name(str(template))}")
    print(f"wrote {sanitize.name(str(sheet))}\nthen: ctsim lab check {ex.number} {sanitize.name(str(template))}")
    return 0


def _start_notebook(ex, folder: Path, lang: str, extra: list[str]) -> int:
    folder.mkdir(parents=True, exist_ok=True)
    existed = (folder / f"exercise{ex.number}.ipynb").exists()
    path = write_notebook(ex, folder, lang, extra)
    shown = sanitize.name(str(path))
    print(f"kept {shown} (it exists; delete it for a fresh notebook)" if existed else f"wrote {shown}")
    print(f"then: open it in Jupyter, or ctsim lab check {ex.number} {shown}")
    return 0
