"""Checking one student file against one exercise: every scenario in turn, a row each.

The checker of the exercise compares; this module keeps it honest: it catches whatever the
student's code does (a `StudentError`) and turns it into a failing row with a hint, hides the
values of hidden scenarios, writes the figures of public ones, and scores the whole.
"""

from __future__ import annotations

import secrets
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sim import sanitize
from sim.lab.artifacts import Tracks, write
from sim.lab.exercise import Exercise, Scenario, shared_hints
from sim.lab.student import Student, StudentError
from sim.lab.unfinished import Gap, gap
from sim.sandbox.box import human_size
from sim.world.spec import WorldSpec

HIDDEN = "(hidden)"
HIDDEN_IN = {"en": HIDDEN, "de": "(verdeckt)"}
"""What a hidden row shows for its values, by language."""
STARTUP_CPU = 10.0
"""CPU seconds a student's process may use besides the scenarios' time limits (Python, numpy)."""


@dataclass
class Outcome:
    """What a checker found in one scenario. `hint`: a key of the exercise's or the shared hints
    (None when passed), formatted with `hint_args`; `matches`: the typical mistakes whose result
    equals the student's here (passed or not; None: not compared), in the exercise's order;
    `tracks` (and `world`) for the figures."""

    expected: str
    got: str
    passed: bool
    tolerance: str = ""
    hint: str | None = None
    hint_args: dict[str, Any] = field(default_factory=dict)
    tracks: Tracks | None = None
    world: WorldSpec | None = None
    matches: tuple[str, ...] | None = None


@dataclass
class Row:
    """One line of the table; `problem` is the key of its hint (what went wrong)."""

    scenario: str
    expected: str
    got: str
    tolerance: str
    passed: bool
    hint: str = ""
    hidden: bool = False
    problem: str = ""
    output: str = ""
    """What the student's code printed during this scenario (shown only where the row's values are)."""
    values: tuple[str, str] = ("", "")
    """Expected and got even of a hidden row: for the teacher's files only (CSV, JUnit)."""
    matches: tuple[str, ...] | None = None
    """The typical mistakes whose result equals the student's in this scenario (see `Outcome`)."""
    hint_args: dict[str, Any] = field(default_factory=dict)


@dataclass
class CheckReport:
    """All rows of one file, the seed of its hidden scenarios, the score and what was written;
    `output`: the start of what the student's code printed while loading and in the public
    scenarios (a hidden scenario's output stays in its row); `degraded`: checked without isolation."""

    exercise: int
    file: str
    seed: int
    rows: list[Row]
    points: float
    artifacts: list[Path] = field(default_factory=list)
    output: str = ""
    degraded: bool = False

    @property
    def passed(self) -> bool:
        return bool(self.rows) and all(row.passed for row in self.rows)

    @property
    def score(self) -> float:
        """Points for the share of scenarios passed."""
        return self.points * sum(row.passed for row in self.rows) / len(self.rows) if self.rows else 0.0

    @property
    def score_text(self) -> str:
        """The score as people read it: "1.8/10"."""
        return f"{round(self.score, 1):g}/{self.points:g}"


def fresh_seed() -> int:
    """A seed nobody chose: the student cannot tune their code to the hidden scenarios."""
    return secrets.randbits(32)


def check_file(exercise: Exercise, path: str | Path, lang: str = "en", seed: int | None = None, out: Path | None = None,
               folder: bool = False, degraded: bool = False, runner: type[Student] = Student) -> CheckReport:  # fmt: skip
    """Run `exercise`'s checker on the student's file over its public and hidden scenarios, the
    file in a sandbox of its own (with its whole folder if `folder`; without isolation only if
    `degraded` and bubblewrap is missing). `runner`: what runs the file (a stand-in of
    `Student`'s interface runs trusted files in this process, for tests of the checkers alone)."""
    seed = fresh_seed() if seed is None else seed
    shared = shared_hints()
    report = CheckReport(exercise.number, str(path), seed, [], exercise.points)
    scenarios = exercise.scenarios(seed, out)
    unfinished = gap(exercise.template(), Path(path))
    if unfinished is not None:  # (said at once: every scenario would only say the same, seconds later)
        report.rows = [_not_written(exercise, scenario, unfinished, lang, shared) for scenario in scenarios]
        return report
    cpu = exercise.time_limit * len(scenarios) + STARTUP_CPU
    with runner(path, exercise.modules, cpu, folder, degraded, exercise.wall(len(scenarios))) as student:
        for scenario in scenarios:
            if student.spent:
                report.rows.append(_not_run(exercise, scenario, student, lang, shared))
                continue
            row, outcome = _one(exercise, scenario, student, lang, shared)
            row.output = student.take_output()
            report.rows.append(row)
            if outcome is not None and outcome.tracks and scenario.out is not None:
                report.artifacts += write(scenario.out, outcome.tracks, outcome.world)
            if row.problem in FATAL:
                break
        report.degraded = student.degraded
    report.output = "".join(row.output for row in report.rows if not row.hidden)
    _name_the_mistake(exercise, report.rows, lang, shared)
    return report


def _name_the_mistake(exercise: Exercise, rows: list[Row], lang: str, shared: dict) -> None:
    """One mistake for the whole file where one explains every compared row (its result equals
    the student's in each, passed or failed: a mistake that would have failed a row the student
    passed is not theirs): every failing row that it explains gets its hint. Where none explains
    all, each row keeps its own."""
    compared = [row for row in rows if row.matches is not None]
    if not any(not row.passed for row in compared):
        return
    common = [key for key in next(row.matches for row in compared if not row.passed) if all(key in row.matches for row in compared)]
    if not common:
        return
    for row in rows:
        if not row.passed and row.matches is not None and common[0] in row.matches:
            row.problem, row.hint = common[0], exercise.hint(common[0], lang, shared, **row.hint_args)


def _not_run(exercise: Exercise, scenario: Scenario, student: Student, lang: str, shared: dict) -> Row:
    """The row of a scenario left when the submission's time was spent."""
    hint = exercise.hint("budget", lang, shared, budget=student.wall)
    got = f"not run: the submission's {student.wall:g} s were spent"
    return Row(scenario.label(lang), HIDDEN_IN[lang] if scenario.hidden else "", got, "", False, hint, scenario.hidden, "budget", values=("", got))


def _not_written(exercise: Exercise, scenario: Scenario, unfinished: Gap, lang: str, shared: dict) -> Row:
    """The row of a scenario not run because the file is no solution yet (`sim.lab.unfinished`)."""
    what = {"placeholder": f"{unfinished.name}() raises NotImplementedError, the template's placeholder", "undefined": f"your file defines no {unfinished.name}"}
    got = f"not run: {what[unfinished.kind]}"
    hint = exercise.hint(unfinished.kind, lang, shared, name=unfinished.name)
    return Row(scenario.label(lang), HIDDEN_IN[lang] if scenario.hidden else "", got, "", False, hint, scenario.hidden, unfinished.kind, values=("", got))


FATAL = ("load", "forbidden")
"""Problems that fail every scenario the same way: the file does not load, or imports what is not there."""


def _one(exercise: Exercise, scenario: Scenario, student: Student, lang: str, shared: dict) -> tuple[Row, Outcome | None]:
    student.begin(exercise.time_limit)
    try:
        outcome = exercise.checker.check(scenario, student)
    except StudentError as err:
        where = f" {_at_line(lang)} {err.line}" if err.line else ""
        key = f"{err.kind}_{err.exception}" if f"{err.kind}_{err.exception}" in exercise.hints else err.kind  # raised_ZeroDivisionError
        hint = exercise.hint(key, lang, shared, limit=exercise.time_limit, where=where, budget=student.wall,
                             memory=human_size(student.box.limits.memory), output=human_size(student.box.limits.output))  # fmt: skip
        got = err.public if scenario.hidden else err.detail
        row = Row(scenario.label(lang), HIDDEN_IN[lang] if scenario.hidden else "", got, "", False, hint, scenario.hidden, key, values=("", err.detail))
        return row, None
    problem = "" if outcome.passed else outcome.hint or (outcome.matches or ("wrong",))[0]
    hint = exercise.hint(problem, lang, shared, **outcome.hint_args) if problem else ""
    values = (outcome.expected, outcome.got)
    shown = (HIDDEN_IN[lang],) * 2 if scenario.hidden else values
    row = Row(scenario.label(lang), *shown, outcome.tolerance, outcome.passed, hint, scenario.hidden, problem, values=values,
              matches=outcome.matches if outcome.passed or outcome.hint is None else None, hint_args=outcome.hint_args)  # fmt: skip
    return row, outcome


DEGRADED = "DEGRADED: run without isolation (bubblewrap missing); the code could read or change files"


def check_and_print(exercise: Exercise, file: Path, shown: str | Path, lang: str, out: Path | None = None, degraded: bool = False) -> CheckReport:
    """What `ctsim lab check` and a notebook's check cell do: check `file` (named `shown`), print
    the table, what the code printed and what was written, into `out` or else a new folder of
    this check's own (`check_folder`); the report."""
    folder = out if out is not None else check_folder(exercise, Path(shown))
    report = check_file(exercise, file, lang, out=folder, degraded=degraded)
    print(f"exercise {exercise.number}: {exercise.title[lang]}  ({sanitize.name(str(shown))}, scenario seed {report.seed})")
    if report.degraded:
        print(DEGRADED)
    print(table(report, lang))
    if report.output:
        print(f"your code printed:\n{sanitize.terminal(report.output)}")
    for path in report.artifacts:
        print(f"  wrote {sanitize.name(str(path))}")
    if out is None and not report.artifacts:
        shutil.rmtree(folder, ignore_errors=True)  # (nothing drawn: no empty folder left behind)
    return report


def check_folder(exercise: Exercise, file: Path) -> Path:
    """A new folder for one check's figures and recordings, in the temporary folder (not where
    the user stands): checks of several students, or of one again, never overwrite each other."""
    stem = "".join(c if c.isalnum() else "-" for c in file.stem)[:40] or "file"
    return Path(tempfile.mkdtemp(prefix=f"ctsim-lab{exercise.number}-{stem}-"))


def _at_line(lang: str) -> str:
    return {"en": "at line", "de": "in Zeile"}[lang]


CELL = 48
"""Widest cell of the table (characters); a longer `got` is said whole on a line of its own."""


def table(report: CheckReport, lang: str = "en") -> str:
    """The report as a text table with the hints under failing rows (safe for a terminal)."""
    words = {"en": ("scenario", "expected", "got", "tolerance", "result", "pass", "FAIL", "hint", "score"),
             "de": ("Szenario", "erwartet", "erhalten", "Toleranz", "Ergebnis", "ok", "FEHLER", "Hinweis", "Punkte")}[lang]  # fmt: skip
    columns = [[sanitize.name(c) for c in (r.scenario, r.expected, r.got, r.tolerance)] + [words[5] if r.passed else words[6]] for r in report.rows]
    widths = [max([len(words[i])] + [min(len(c[i]), CELL) for c in columns]) for i in range(5)]
    line = lambda cells: "  ".join(str(c)[:CELL].ljust(w) for c, w in zip(cells, widths)).rstrip()
    lines = [line(words[:5]), line(["-" * w for w in widths])]
    said: list[str] = []  # (the lines under the row before: rows that fail alike say them once)
    for row, cells in zip(report.rows, columns):
        lines.append(line(cells))
        under = [f"    {words[2]}: {sanitize.name(row.got, 1000)}"] if len(row.got) > CELL else []  # (an exception's whole message)
        under += [f"    {words[7]}: {sanitize.name(row.hint, 1000)}"] if row.hint else []
        lines += [text for text in under if text not in said]
        said = under
    passed = sum(r.passed for r in report.rows)
    lines.append(f"{words[8]}: {report.score_text} ({passed}/{len(report.rows)})")
    return "\n".join(lines)


def fmt(values: Any, digits: int = 4) -> str:
    """Numbers for the table: a scalar or a short vector."""
    array = np.atleast_1d(np.asarray(values, dtype=np.float64))
    text = ", ".join(f"{v:.{digits}g}" for v in array)
    return text if array.size == 1 else f"({text})"


def differing(expected: Any, got: Any, digits: int = 4) -> tuple[str, str]:
    """A failing row's `expected` and `got` as text, with enough significant digits (from
    `digits` up to 17) that two different values never read the same."""
    same = np.array_equal(np.asarray(expected, dtype=np.float64), np.asarray(got, dtype=np.float64))
    for shown in range(digits, 18):
        pair = fmt(expected, shown), fmt(got, shown)
        if same or pair[0] != pair[1]:
            break
    return pair


def close(got: Any, expected: Any, tolerance: float) -> bool:
    """Every component within `tolerance` (absolute), an infinity matching one of either sign."""
    got, expected = np.asarray(got, dtype=np.float64), np.asarray(expected, dtype=np.float64)
    if got.shape != expected.shape:
        return False
    infinite = np.isinf(expected)
    if (np.isinf(got) != infinite).any():
        return False
    return bool(np.all(np.abs(got[~infinite] - expected[~infinite]) <= tolerance))


def diagnose(got: Any, mistakes: dict[str, Any], tolerance: float) -> str | None:
    """The first typical mistake whose result the student's matches (its hint key), or None."""
    return next((key for key, value in mistakes.items() if close(got, value, tolerance)), None)
