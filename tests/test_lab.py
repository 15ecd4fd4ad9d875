"""ctsim lab: each exercise's reference solution passes, typical wrong ones fail with the right
hint, and whatever a student's file does the checker survives with a clear message."""

from __future__ import annotations

import csv
import dataclasses
import json
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from sim.cli.entry import main
from sim.lab import check_file, exercise
from sim.lab.exercise import shared_hints
from sim.lab.grading import grade

SOLUTIONS = Path(__file__).parent / "lab"
SEED = 7  # any seed: the reference must pass every draw; a fixed one keeps the test repeatable

WRONG = {
    1: ["swapped", "degrees", "straight", "radius_factor", "half_track"],
    2: ["euler", "old_heading", "degrees", "swapped", "straight", "euler_new", "no_chord", "sin_cos", "half_track", "wrapped"],
    3: ["euler", "swapped", "hardcoded", "end_heading", "no_chord", "sin_cos", "half_track", "millimetres", "ticks", "diameter_2pi",
        "cumulative"],
    4: ["axle", "chord", "flipped", "no_my"],
    5: ["heading", "slow", "collision"],
    6: ["swapped", "inverted", "track_only", "degrees"],
    7: ["lost", "stopped", "slow"],
}


def quick(number: int, hidden: int | None = None):
    """The exercise with fewer hidden scenarios (the run-based ones take a second each, UMBmark's
    four squares four)."""
    return dataclasses.replace(exercise(number), hidden=(1 if number == 6 else 2) if hidden is None else hidden)


PASSING = [(number, "reference") for number in WRONG if number != 7] + [(7, "own"), (3, "wrapped")]  # 3: θ wrapped or not


@pytest.mark.parametrize(("number", "solution"), PASSING)
def test_the_reference_solution_passes_every_scenario(number: int, solution: str) -> None:
    report = check_file(quick(number), SOLUTIONS / f"ex{number}" / f"{solution}.py", seed=SEED)
    assert report.passed, [(r.scenario, r.got, r.hint) for r in report.rows if not r.passed]
    assert report.score == report.points


@pytest.mark.parametrize(("number", "mistake"), [(n, m) for n, ms in WRONG.items() for m in ms])
def test_a_typical_mistake_fails_with_its_hint(number: int, mistake: str) -> None:
    ex = quick(number)
    report = check_file(ex, SOLUTIONS / f"ex{number}" / f"{mistake}.py", seed=SEED)
    failed = [r for r in report.rows if not r.passed]
    assert failed and not report.passed
    assert any(r.problem == mistake for r in failed), [(r.scenario, r.hint) for r in failed]
    assert all(r.hint and r.hint != r.problem for r in failed)  # a text of its own, not the bare key


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


BAD = {
    "raises": ("def turn(*a):\n    raise ValueError(f'secret {a}')\n", "raised", "turn() raised ValueError at line 2"),
    "hangs": ("def turn(*a):\n    while True:\n        pass\n", "timeout", "took longer than the time limit"),
    "shape": ("def turn(*a):\n    return 1.0, 2.0\n", "shape", "returned shape (2,); expected (4,)"),
    "nan": ("def turn(*a):\n    return [float('nan')] * 4\n", "nan", "returned NaN"),
    "type": ("def turn(*a):\n    return object()\n", "type", "returned a object"),
    "truth": ("import sim.run\ndef turn(*a):\n    return 0, 0, 0, 0\n", "forbidden", "import of sim.run at line 1 is not available here"),
    "truth_late": ("def turn(*a):\n    from sim.world import physics\n    return 0, 0, 0, 0\n", "forbidden", "import of sim.world at line 2 is not available here"),
    "exits": ("import os\ndef turn(*a):\n    os._exit(3)\n", "crash", "ended the checking process"),
    "syntax": ("def turn(*a)\n    return 1\n", "load", "loading your file raised SyntaxError at line 1"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_student_code_fails_with_a_clear_message_and_leaks_nothing_hidden(tmp_path: Path, case: str) -> None:
    text, kind, message = BAD[case]
    ex = dataclasses.replace(exercise(1), time_limit=0.5, hidden=2)
    report = check_file(ex, write(tmp_path, "icc.py", text), seed=SEED)
    assert not report.passed and report.score == 0
    assert message in report.rows[0].got
    assert report.rows[0].problem == kind and "{" not in report.rows[0].hint
    assert report.rows[0].hint.startswith(ex.hint(kind, "en", shared_hints(), limit=0.5).split("{")[0])
    hidden = [r for r in report.rows if r.hidden]
    assert all("secret" not in r.got and r.expected == "(hidden)" for r in hidden)


def test_hidden_scenarios_differ_by_seed_and_repeat_with_it() -> None:
    ex = exercise(1)
    params = lambda seed: [s.params for s in ex.scenarios(seed) if s.hidden]
    assert params(1) == params(1)
    assert params(1) != params(2)


def test_check_writes_a_recording_and_figures_of_a_run(tmp_path: Path) -> None:
    from rerun.chunk import RrdReader  # noqa: F401  (readable, not just present)

    report = check_file(quick(3, hidden=0), SOLUTIONS / "ex3" / "reference.py", seed=SEED, out=tmp_path)
    names = {p.name for p in report.artifacts}
    assert {"run.rrd", "trajectories.png", "errors.png"} <= names
    assert all(p.stat().st_size > 1000 for p in report.artifacts)


def test_grade_writes_csv_gradescope_and_junit(tmp_path: Path) -> None:
    folder = tmp_path / "subs"
    folder.mkdir()
    for name in ("reference", "swapped", "straight"):
        (folder / f"{name}.py").write_text((SOLUTIONS / "ex1" / f"{name}.py").read_text())
    reports, _ = grade(exercise(1), folder, tmp_path / "out", seed=SEED, jobs=2)
    rows = list(csv.DictReader((tmp_path / "out" / "grades.csv").open()))
    assert {r["student"]: r["score"] == "10" for r in rows} == {"reference": True, "straight": False, "swapped": False}
    results = json.loads((tmp_path / "out" / "gradescope" / "swapped" / "results.json").read_text())
    assert results["score"] < 10 and any(t["status"] == "failed" for t in results["tests"])
    suites = ET.parse(tmp_path / "out" / "junit.xml").getroot()
    assert {s.get("name"): int(s.get("failures")) > 0 for s in suites} == {"reference": False, "straight": True, "swapped": True}


def test_cli_start_then_check_the_untouched_template_fails_with_status_1(tmp_path: Path, capsys) -> None:
    assert main(["lab", "--lang", "de", "start", "1", str(tmp_path)]) == 0
    assert "Aufgabe 1" in (tmp_path / "exercise1.md").read_text()
    assert main(["lab", "check", "1", str(tmp_path / "icc.py"), "--out", str(tmp_path / "out")]) == 1
    assert "NotImplementedError" in capsys.readouterr().out
    assert main(["lab", "start", "99"]) == 2
    assert main(["lab", "check", "1", str(tmp_path / "missing.py")]) == 2


def test_a_teacher_adds_an_exercise_in_a_folder_of_their_own(tmp_path: Path, capsys) -> None:
    folder = tmp_path / "mine" / "double"
    folder.mkdir(parents=True)
    (folder / "exercise.toml").write_text('number = 42\nfile = "double.py"\ntitle = { en = "Double", de = "Doppelt" }\n'
                                          'summary = { en = "x2", de = "x2" }\n[[example]]\nx = 3.0\n')
    for name in ("sheet.en.md", "sheet.de.md"):
        (folder / name).write_text("# Double\n")
    (folder / "template.py").write_text("def double(x):\n    return x\n")
    (folder / "checker.py").write_text(
        "from sim.lab.checking import Outcome\n"
        "def check(scenario, student):\n"
        "    got = student.call('double', scenario['x'])\n"
        "    return Outcome(str(2 * scenario['x']), str(got), got == 2 * scenario['x'])\n")
    assert main(["lab", "--exercises", str(tmp_path / "mine"), "list"]) == 0
    assert "Double" in capsys.readouterr().out
    solution = write(tmp_path, "double.py", "def double(x):\n    return 2 * x\n")
    assert main(["lab", "--exercises", str(tmp_path / "mine"), "check", "42", str(solution), "--out", str(tmp_path / "o")]) == 0


def test_a_failing_row_shows_expected_and_got_to_enough_digits_to_differ() -> None:
    row = check_file(quick(3, hidden=0), SOLUTIONS / "ex3" / "no_chord.py", seed=SEED).rows[0]
    assert not row.passed and row.problem == "no_chord"
    assert row.expected != row.got  # the chord's few micrometres show, however many digits that takes


def test_half_the_track_on_the_spot_is_named_as_such_not_as_the_spot_case() -> None:
    report = check_file(quick(1, hidden=0), SOLUTIONS / "ex1" / "half_track.py", seed=SEED)
    assert next(r for r in report.rows if r.scenario == "on the spot").problem == "half_track"


def test_gradescope_output_carries_values_error_line_and_hint_and_scores_read_short(tmp_path: Path) -> None:
    folder = tmp_path / "subs"
    folder.mkdir()
    (folder / "euler.py").write_text((SOLUTIONS / "ex2" / "euler.py").read_text())
    (folder / "syntax.py").write_text("def step(*a)\n    return 1\n")
    reports, _ = grade(exercise(2), folder, tmp_path / "out", seed=SEED)
    failed = [t for t in json.loads((tmp_path / "out" / "gradescope" / "euler" / "results.json").read_text())["tests"] if t["status"] == "failed"]
    visible = next(t for t in failed if t["visibility"] == "visible")["output"]
    assert "expected: (" in visible and "got: (" in visible and "Euler" in visible
    syntax = json.loads((tmp_path / "out" / "gradescope" / "syntax" / "results.json").read_text())["tests"][0]["output"]
    assert "SyntaxError at line 1" in syntax and "fix the error at line 1" in syntax
    euler = next(r for r in reports if r.file.endswith("euler.py"))
    assert euler.score_text == f"{round(euler.score, 1):g}/10" and len(euler.score_text) <= 6


def test_without_bubblewrap_grading_refuses_unless_degraded_and_then_says_so_everywhere(tmp_path: Path, monkeypatch) -> None:
    from sim.lab import grading
    from sim.sandbox import SandboxUnavailable, launch

    missing = lambda: "bubblewrap (bwrap) is not installed"
    monkeypatch.setattr(launch, "unavailable", missing)
    monkeypatch.setattr(grading, "unavailable", missing)
    folder = tmp_path / "subs"
    folder.mkdir()
    (folder / "alice.py").write_text((SOLUTIONS / "ex1" / "reference.py").read_text())
    with pytest.raises(SandboxUnavailable, match="--degraded"):
        grade(exercise(1), folder, tmp_path / "out", seed=SEED)
    assert not (tmp_path / "out").exists()
    reports, _ = grade(exercise(1), folder, tmp_path / "out", seed=SEED, degraded=True)
    assert reports[0].passed and reports[0].degraded
    assert next(csv.DictReader((tmp_path / "out" / "grades.csv").open()))["isolation"] == "degraded (no isolation)"
    assert "DEGRADED" in json.loads((tmp_path / "out" / "gradescope" / "alice" / "results.json").read_text())["output"]
    assert main(["lab", "check", "1", str(folder / "alice.py")]) == 2  # refused, with the reason on stderr


def test_a_submission_that_sleeps_at_every_start_and_call_is_ended_when_its_time_is_spent(tmp_path: Path) -> None:
    text = "import time\ntime.sleep(2)\ndef step(*a):\n    time.sleep(3600)\n"
    ex = dataclasses.replace(exercise(2), time_limit=0.5, hidden=3, budget=4.0)
    report = check_file(ex, write(tmp_path, "forward.py", text), seed=SEED)
    assert not any(r.passed for r in report.rows) and len(report.rows) == 6
    assert report.rows[-1].problem == "budget" and "not run" in report.rows[-1].got  # not started again for each scenario
    assert "4 s of time" in report.rows[-1].hint


PRINTS = (SOLUTIONS / "ex2" / "reference.py").read_text() + (
    "\n_step = step\ndef step(*a):\n    print('inputs', a)\n    return _step(*a)\n")


def test_what_a_hidden_scenario_printed_stays_in_its_row(tmp_path: Path) -> None:
    folder = tmp_path / "subs"
    folder.mkdir()
    (folder / "printer.py").write_text(PRINTS)
    reports, _ = grade(quick(2), folder, tmp_path / "out", seed=SEED)
    report = reports[0]
    assert report.passed
    hidden = [r for r in report.rows if r.hidden]
    assert all("inputs" in r.output for r in report.rows)
    assert all(r.output not in report.output for r in hidden) and "inputs (0.0, 0.0, 0.0, 0.1, 0.2" in report.output
    results = json.loads((tmp_path / "out" / "gradescope" / "printer" / "results.json").read_text())
    for row, test in zip(report.rows, results["tests"]):
        assert row.output.splitlines()[0] in test["output"]
        assert test["visibility"] == ("after_published" if row.hidden else "visible")
        assert row.hidden == (row.output.splitlines()[0] not in results["output"])


def test_the_teacher_s_files_carry_hidden_values_and_unrounded_scores(tmp_path: Path) -> None:
    folder = tmp_path / "subs"
    folder.mkdir()
    (folder / "euler.py").write_text((SOLUTIONS / "ex2" / "euler.py").read_text())
    reports, _ = grade(exercise(2), folder, tmp_path / "out", seed=SEED)
    row = next(csv.DictReader((tmp_path / "out" / "grades.csv").open()))
    assert row["score"] == f"{round(reports[0].score, 4):g}" and len(row["score"].split(".")[-1]) > 1
    assert row["hidden_values"].count("expected (") == exercise(2).hidden
    failures = [case.find("failure").text for case in ET.parse(tmp_path / "out" / "junit.xml").getroot().iter("testcase")
                if case.get("name").startswith("hidden") and case.find("failure") is not None]  # fmt: skip
    assert failures and all("expected: (" in text and "got: (" in text for text in failures)


def test_a_folder_of_notebooks_and_files_is_graded_alike(tmp_path: Path) -> None:
    from sim.lab.notebook import write_notebook

    folder = tmp_path / "subs"
    folder.mkdir()
    path = write_notebook(exercise(2), tmp_path)
    document = json.loads(path.read_text())
    solution = next(c for c in document["cells"] if "solution" in c["metadata"].get("tags", []))
    solution["source"] = "%%writefile forward.py\n" + (SOLUTIONS / "ex2" / "reference.py").read_text()
    (folder / "nora.ipynb").write_text(json.dumps(document))
    (folder / "nora.py").write_text((SOLUTIONS / "ex2" / "euler.py").read_text())
    (folder / "olaf.ipynb").write_text('{"cells": [}')
    grade(quick(2), folder, tmp_path / "out", seed=SEED)
    rows = {r["student"]: r for r in csv.DictReader((tmp_path / "out" / "grades.csv").open())}
    assert rows["nora.ipynb"]["score"] == "10" and rows["nora.py"]["score"] != "10"
    assert rows["olaf"]["score"] == "0" and "not a notebook (not JSON" in rows["olaf"]["first_problem"]


def test_every_problem_has_a_hint_of_its_own_in_both_languages() -> None:
    shared = shared_hints()
    for kind in ("load", "raised", "timeout", "crash", "forbidden", "type", "shape", "nan", "wrong", "budget", "protocol", "output", "memory",
                 "placeholder", "undefined"):
        assert set(shared[kind]) == {"en", "de"} and all(len(text.split()) > 5 for text in shared[kind].values()), kind


def test_german_sheets_command_with_lang_after_the_file_is_taken(tmp_path: Path, capsys) -> None:
    path = tmp_path / "forward.py"
    path.write_text((SOLUTIONS / "ex2" / "reference.py").read_text())
    assert main(["lab", "check", "2", str(path), "--lang", "de", "--out", str(tmp_path / "out")]) == 0
    printed = capsys.readouterr().out
    assert "Viertelkreis" in printed and "verdeckt 1" in printed and "(verdeckt)" in printed and "Punkte: 10/10" in printed


def test_grading_without_a_seed_draws_a_fresh_one_each_time(tmp_path: Path) -> None:
    folder = tmp_path / "subs"
    folder.mkdir()
    (folder / "alice.py").write_text((SOLUTIONS / "ex1" / "reference.py").read_text())
    seeds = {grade(quick(1), folder, tmp_path / f"out{i}")[0][0].seed for i in range(2)}
    assert len(seeds) == 2  # 32 random bits each: the same twice once in four billion


def test_lab_help_lists_the_lab_s_own_exit_statuses(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["lab", "--help"])
    printed = capsys.readouterr().out
    assert "every submission graded" in printed and "a scenario failed" in printed and "controller raised" not in printed


def test_a_students_whole_exception_message_is_printed_not_cut_to_the_cell():
    """A long message (the untouched template's NotImplementedError) is said whole under its row."""
    from sim.lab.checking import CELL, CheckReport, Row, table

    message = "raised NotImplementedError: write forward() here: turn the wheel ticks into metres, then the pose (see the sheet)"
    report = CheckReport(2, "forward.py", 0, [Row("circle", "(1, 2, 3)", message, "1e-6", False)], 10.0)
    lines = table(report).splitlines()
    assert len(message) > CELL and f"    got: {message}" in lines
    assert "got:" not in table(dataclasses.replace(report, rows=[Row("circle", "1", "2", "1e-6", False)]))


class NeverRun:
    """A stand-in for `Student` that fails the test if the check starts the student's file at all."""

    def __init__(self, *args, **kwargs):
        raise AssertionError("the student's file was run")


@pytest.mark.parametrize("number", sorted(WRONG))
def test_the_untouched_template_is_told_before_anything_runs(number: int, tmp_path: Path) -> None:
    """Each scenario would only say the same NotImplementedError, seconds of runs and replays later."""
    from sim.lab.unfinished import placeholders

    ex = exercise(number)
    report = check_file(ex, write(tmp_path, ex.file, ex.template()), seed=SEED, runner=NeverRun)
    assert len(report.rows) == len(ex.scenarios(SEED)) and report.score == 0
    assert {r.problem for r in report.rows} == {"placeholder"}
    assert all(f"{placeholders(ex.template())[0]}() raises NotImplementedError" in r.got and "not run" in r.got for r in report.rows)
    assert {r.hint for r in report.rows} == {ex.hint("placeholder", "en", shared_hints(), name=placeholders(ex.template())[0])}


UNFINISHED = {
    "docstring kept": ('def turn(*a):\n    """Mine."""\n    raise NotImplementedError\n', "placeholder"),
    "defined again": ("def turn(*a):\n    return 0, 0, 0, 0\n\ndef turn(*a):\n    raise NotImplementedError('later')\n", "placeholder"),
    "no such name": ("def icc(*a):\n    return 0, 0, 0, 0\n", "undefined"),
}
STARTED = {
    "written": "def turn(*a):\n    return 0, 0, 0, 0\n",
    "raises after work": "def turn(*a):\n    x = 1\n    raise NotImplementedError(x)\n",
    "imported": "from helper import turn\n",
    "star import": "from helper import *\n",
    "rebound": "def turn(*a):\n    raise NotImplementedError\n\nturn = lambda *a: (0, 0, 0, 0)\n",
    "by its name in a string": "globals()['turn'] = lambda *a: (0, 0, 0, 0)\n",
    "does not parse": "def turn(*a)\n",
}


@pytest.mark.parametrize("case", sorted(UNFINISHED))
def test_a_file_that_is_no_solution_yet_is_told_at_once(case: str, tmp_path: Path) -> None:
    text, problem = UNFINISHED[case]
    report = check_file(exercise(1), write(tmp_path, "icc.py", text), seed=SEED, runner=NeverRun)
    assert {r.problem for r in report.rows} == {problem} and "turn" in report.rows[0].got


@pytest.mark.parametrize("case", sorted(STARTED))
def test_a_file_the_text_cannot_judge_is_run(case: str, tmp_path: Path) -> None:
    from sim.lab.unfinished import gap

    assert gap(exercise(1).template(), write(tmp_path, "icc.py", STARTED[case])) is None


def test_a_pipe_for_a_file_is_not_read_by_the_template_check(tmp_path: Path) -> None:
    import os

    from sim.lab.unfinished import gap

    os.mkfifo(tmp_path / "icc.py")  # (read without O_NONBLOCK, this would wait for a writer forever)
    assert gap(exercise(1).template(), tmp_path / "icc.py") is None


def test_each_check_draws_into_a_new_folder_of_its_own_not_here(tmp_path: Path, monkeypatch, capsys) -> None:
    """Two students checked one after the other (or one twice) keep both sets of figures; the
    current folder gets nothing; `--out` puts them where asked."""
    import tempfile

    here, scratch = tmp_path / "here", tmp_path / "scratch"
    here.mkdir()
    scratch.mkdir()
    monkeypatch.chdir(here)
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    printed = ""
    for name in ("alice", "bob"):
        write(here, f"{name}.py", (SOLUTIONS / "ex2" / "reference.py").read_text())
        assert main(["lab", "check", "2", f"{name}.py"]) == 0
        printed += capsys.readouterr().out
    folders = sorted(scratch.iterdir())
    assert [f.name.split("-")[:2] for f in folders] == [["ctsim", "lab2"]] * 2 and folders[0].name != folders[1].name
    assert [f.name.split("-")[2] for f in folders] in (["alice", "bob"], ["bob", "alice"])  # (the rest is random)
    assert all(any(f.rglob("trajectories.png")) for f in folders)
    assert sorted(p.name for p in here.iterdir()) == ["alice.py", "bob.py"]
    assert all(f"wrote {f}" in printed for f in folders)  # (where they are, said)
    assert main(["lab", "check", "2", "alice.py", "--out", "mine"]) == 0
    assert any((here / "mine").rglob("trajectories.png")) and len(list(scratch.iterdir())) == 2
