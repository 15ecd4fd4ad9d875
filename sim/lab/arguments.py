"""The options of `ctsim lab` (standard library only: building the command line imports nothing
of the lab itself)."""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

EXIT_STATUSES = """exit status:
  0    list, start: done; check: every scenario passed; grade: every submission graded
       (failing students too: their grades are in the files)
  1    check: a scenario failed (the table says which and why); grade: the grader failed on a
       submission (a ctsim bug, printed; the others are graded all the same)
  2    a user error (bad option, exercise, file or folder; a malformed notebook), or bubblewrap
       missing without --degraded
  130  interrupted by Ctrl-C"""
LANG = {"choices": ("en", "de"), "help": "language of sheets, hints and tables (default: en)"}


def _positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def add_parser(commands: argparse._SubParsersAction, handler: Callable[[argparse.Namespace], int]) -> None:
    """`ctsim lab` and its actions on `commands`, run by `handler`. `--lang` is taken before the
    action or after it (`ctsim lab check 2 forward.py --lang de`, as the German sheets write)."""
    lab = commands.add_parser("lab", help="lab exercises with automatic checking", epilog=EXIT_STATUSES,
                              description="Exercises on kinematics and odometry: write the sheet and template, check your file, grade a folder of submissions.")  # fmt: skip
    lab.add_argument("--lang", default="en", **LANG)
    lab.add_argument("--exercises", action="append", default=[], metavar="DIR", help="a folder with more exercises (one sub-folder each), repeatable")
    actions = lab.add_subparsers(dest="lab_command", metavar="ACTION", required=True)

    def action(name: str, help: str) -> argparse.ArgumentParser:
        parser = actions.add_parser(name, help=help, epilog=EXIT_STATUSES)
        parser.add_argument("--lang", default=argparse.SUPPRESS, **LANG)  # after the action too; unset keeps the one before
        return parser

    action("list", "the exercises")
    start = action("start", "write the exercise sheet (Markdown) and the template to fill in")
    start.add_argument("number", type=int)
    start.add_argument("dir", nargs="?", type=Path, default=Path("."), help="folder to write into (default: here)")
    start.add_argument("--notebook", action="store_true", help="write the exercise as a Jupyter notebook instead (sheet, your solution's cell, a cell that checks it)")
    check = action("check", "check your file on the examples and on hidden scenarios")
    check.add_argument("number", type=int)
    check.add_argument("file", type=Path, help="your file, or the notebook of `lab start --notebook`")
    check.add_argument("--out", type=Path, metavar="DIR", help="folder for figures and recordings (default: a new one for each check in the temporary folder, named in the output)")
    check.add_argument("--degraded", action="store_true", help="where bubblewrap is missing, run the file without isolation (said in the result)")
    grade = action("grade", "grade a folder of submissions (.py files, notebooks, or a folder each): CSV, Gradescope results.json, JUnit XML")
    grade.add_argument("number", type=int)
    grade.add_argument("submissions", type=Path, metavar="SUBMISSIONS_DIR")
    grade.add_argument("--out", type=Path, default=None, metavar="DIR", help="folder for the grades (default: SUBMISSIONS_DIR/grades)")
    grade.add_argument("--seed", type=int, help="seed of the hidden scenarios (default: a fresh one each time, written to grades.csv: "
                       "give one only to repeat a grading; a seed used before lets students tune their code to its hidden scenarios)")
    grade.add_argument("--jobs", type=_positive, help="parallel checks (default: number of CPUs)")
    grade.add_argument("--degraded", action="store_true", help="where bubblewrap is missing, grade without isolation (said in every result)")
    lab.set_defaults(handler=handler)
