"""A class folder whose items are not all files a student wrote: pipes and devices for files, hard
links to a classmate's file, notebooks no reader accepts, a student's folder without the file,
strays beside the submissions. Each student is graded or failed with the reason in one line
(never the class's grading failed, never a student left out silently, never another's work graded
as one's own), and every other item is listed with why it was not graded. Graded without
isolation (`degraded`): the only code that runs is the reference solution."""

from __future__ import annotations

import csv
import json
import os
import shutil
import stat
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from sim.cli.entry import main
from sim.lab import exercise
from sim.lab.exercise import ExerciseError
from sim.lab.grading import grade, others, submissions
from sim.lab.notebook import solution_source

REFERENCE = Path(__file__).parent / "lab" / "ex2" / "reference.py"
SEED = 13579


def notebook(source_json: str) -> str:
    """A notebook whose solution cell's source is the raw JSON text `source_json`."""
    return ('{"cells": [{"cell_type": "code", "metadata": {"tags": ["solution"]}, "outputs": [], "execution_count": null, '
            f'"source": {source_json}}}], "metadata": {{}}, "nbformat": 4, "nbformat_minor": 5}}')


UNREADABLE = {
    "digits": notebook('"x = 1\\n", "n": ' + "9" * 5000),  # (past Python's integer-string limit: a ValueError)
    "surrogate": notebook('"x = \\ud800\\n"'),
    "nan": notebook("NaN"),
    "deep": "[" * 100_000 + "]" * 100_000,
    "latin1": notebook('"x = 1\\n"').replace("x", "\xe9"),
    "empty": "",
}
"""Notebooks no reader accepts, each a different exception of reading (the encoding of `latin1`
is Latin-1 below, not UTF-8)."""


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """A flat class: alice (the reference), carol (a hard link to alice's file), bob (a pipe),
    eve (a name with a right-to-left override), the unreadable notebooks, a stray file and folder."""
    folder = tmp_path_factory.mktemp("class") / "subs"
    folder.mkdir()
    shutil.copy(REFERENCE, folder / "alice.py")
    os.link(folder / "alice.py", folder / "carol.py")
    os.mkfifo(folder / "bob.py")
    shutil.copy(REFERENCE, folder / "eve\u202egnp.py")
    for name, text in UNREADABLE.items():
        (folder / f"{name}.ipynb").write_bytes(text.encode("latin-1" if name == "latin1" else "utf-8"))
    (folder / "README.txt").write_text("hand in one .py each")
    (folder / "stray").mkdir()
    out = folder.parent / "grades"
    reports, _ = grade(exercise(2), folder, out, seed=SEED, degraded=True)
    return folder, out, {Path(r.file).stem: r for r in reports}


def first_problem(report) -> tuple[str, str]:
    row = next(r for r in report.rows if not r.passed)
    return row.problem, row.got


def test_every_unreadable_notebook_is_its_students_load_failure_alone(graded):
    _, _, reports = graded
    for name in UNREADABLE:
        problem, got = first_problem(reports[name])
        assert problem == "load" and got.startswith(f"{name}.ipynb: ") and "\n" not in got, (name, got)
    assert reports["alice"].score == 0 and reports["eve\u202egnp"].score == 10  # (the honest student, graded all the same)


def test_a_pipe_is_failed_with_its_reason_not_left_out(graded):
    assert first_problem(graded[2]["bob"]) == ("not a file", "the submission is a named pipe, not a file: not graded")


def test_hard_links_between_two_students_flag_both(graded):
    reports = graded[2]
    assert first_problem(reports["alice"]) == ("link", "the submission is a hard link (shared with carol), not a file of its own: not graded")
    assert first_problem(reports["carol"]) == ("link", "the submission is a hard link (shared with alice), not a file of its own: not graded")


def test_strays_are_listed_with_why(graded):
    folder, out, _ = graded
    listed = {item.name: why for item, why in others(folder, submissions(folder, "forward.py", notebooks=True), out)}
    assert listed == {"README.txt": "not a .py file or notebook",
                      "stray": "a folder beside the students' files (a class folder holds either files or one folder per student)"}  # fmt: skip


def test_the_three_tables_hold_no_character_that_acts_on_a_screen(graded):
    _, out, _ = graded
    junit = (out / "junit.xml").read_text(encoding="utf-8")
    grades = (out / "grades.csv").read_text(encoding="utf-8")
    results = [p.read_text(encoding="utf-8") for p in (out / "gradescope").glob("*/results.json")]
    for text in (junit, grades, *results):
        assert "\u202e" not in text
    assert "eve\\u202egnp" in junit and "eve\\u202egnp" in grades
    assert {row["student"] for row in csv.DictReader(grades.splitlines())} >= {"alice", "bob", "carol", *UNREADABLE}


def test_a_students_folder_without_the_file_is_graded_as_missing(tmp_path):
    folder = tmp_path / "subs"
    for student in ("alice", "bob", ".ipynb_checkpoints"):
        (folder / student).mkdir(parents=True)
    shutil.copy(REFERENCE, folder / "alice" / "forward.py")
    (folder / "bob" / "notes.txt").write_text("forgot it")
    reports, _ = grade(exercise(2), folder, tmp_path / "grades", seed=SEED, degraded=True)
    assert [(Path(r.file).parent.name, r.score) for r in reports] == [("alice", 10), ("bob", 0)]
    assert first_problem(reports[1]) == ("missing", "no forward.py (nor one notebook) in the student's folder: nothing to grade")
    listed = {item.name: why for item, why in others(folder, submissions(folder, "forward.py", notebooks=True))}
    assert listed == {".ipynb_checkpoints": "a hidden folder"}


def test_a_device_handed_in_is_failed_with_its_reason(tmp_path):
    folder = tmp_path / "subs"
    folder.mkdir()
    shutil.copy(REFERENCE, folder / "alice.py")
    try:
        os.mknod(folder / "mallory.py", stat.S_IFCHR | 0o666, os.makedev(1, 3))  # (/dev/null's numbers)
    except PermissionError:
        pytest.skip("making a device file needs root")
    reports, _ = grade(exercise(2), folder, tmp_path / "grades", seed=SEED, degraded=True)
    assert first_problem(reports[1]) == ("not a file", "the submission is a character device, not a file: not graded")


def test_lab_grade_lists_what_it_did_not_grade(graded, capsys):
    folder, _, _ = graded
    assert main(["lab", "grade", "2", str(folder), "--out", str(folder.parent / "again"), "--degraded", "--seed", str(SEED)]) == 0
    out = capsys.readouterr().out
    assert "README.txt: not graded: not a .py file or notebook" in out and "eve\\u202egnp.py" in out and "\u202e" not in out


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(st.binary(max_size=300) | st.text(max_size=300).map(lambda t: t.encode("utf-8", "surrogatepass")) | st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(), lambda inner: st.lists(inner) | st.dictionaries(st.text(), inner),
    max_leaves=20).map(lambda v: json.dumps({"cells": [{"cell_type": "code", "metadata": {"tags": ["solution"]}, "source": v}]}).encode()))
def test_any_file_as_a_notebook_is_read_or_refused_as_the_students(tmp_path, data):
    path = tmp_path / "any.ipynb"
    path.write_bytes(data)
    try:
        assert isinstance(solution_source(path), str)
    except ExerciseError as err:
        assert "\n" not in str(err)
