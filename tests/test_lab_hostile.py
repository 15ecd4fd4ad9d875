"""A class with hostile students: `ctsim lab grade` on exercise 2 over honest submissions and
attacks on the grader. Each attack fails only itself, with a clear reason in the results; the
honest submissions get the grades they get when graded alone; nothing outside the sandboxes is
read, written or left running. One grading serves every test (module-scoped fixture)."""

from __future__ import annotations

import contextlib
import csv
import dataclasses
import io
import json
import os
import shutil
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from sim import sanitize
from sim.cli.entry import main
from sim.lab import exercise
from sim.lab.grading import grade
from sim.sandbox import unavailable

pytestmark = pytest.mark.skipif(unavailable() is not None, reason=f"no OS sandbox here: {unavailable()}")

SOLUTIONS = Path(__file__).parent / "lab" / "ex2"
ROOT = Path(__file__).resolve().parents[1]
SEED = 24680  # any seed; a fixed one keeps the grading repeatable and lets the snoopers look for it
STEP = "def step(x, y, theta, v_left, v_right, track, dt):\n"
REPLIES = "import json, sys\nREPLIES = json.loads(sys.argv[1])['replies']\n"


def json_body(value) -> str:
    return f"json.dumps({value!r}).encode()"


def forge(body: str) -> str:
    """A submission that replaces the guest's encoder: every answer it gives is the bytes `body`
    (a Python expression) however malformed; braces doubled for the ATTACKS' format."""
    text = f"import json, struct, sys\nBODY = {body}\nsys.modules['wire'].dumps = lambda value: struct.pack('>I', len(BODY)) + BODY\n"
    return (text + STEP + "    return [x, y, theta]\n").replace("{", "{{").replace("}", "}}")


SYSCALL = "import ctypes, platform\nfrom confine import NUMBERS\ndef call(name, *args):\n    return ctypes.CDLL(None, use_errno=True).syscall(NUMBERS[platform.machine()][name], *args)\n"

# name -> (code, the row's problem, text its first failing row's `got` holds). {key}, {grades},
# {teacher}, {alice}, {root}, {marker} are host paths the attacker aims at.
ATTACKS = {
    "pickle_reply": (
        "import pickle, struct, sys\n"
        "class Payload:\n    def __reduce__(self):\n        return (open, ({marker!r}, 'w'))\n"
        "def forged(value):\n    body = pickle.dumps(Payload())\n    return struct.pack('>I', len(body)) + body\n"
        "sys.modules['wire'].dumps = forged\n" + STEP + "    return [x, y, theta]\n",
        "protocol", "the answer could not be read"),
    "pickle_raw": (
        REPLIES + "import os, pickle, struct\nclass Payload:\n    def __reduce__(self):\n        return (open, ({marker!r}, 'w'))\n"
        + STEP + "    body = pickle.dumps(Payload())\n    os.write(REPLIES, struct.pack('>I', len(body)) + body)\n    return [x, y, theta]\n",
        "protocol", "the answer could not be read"),
    "fork_rewriter": ("import os\n" + STEP + "    if os.fork() == 0:\n        open({grades!r}, 'w').write('bob,10')\n    return [x, y, theta]\n",
                      "raised", "raised PermissionError at line 3"),
    "thread_rewriter": (
        "import threading, time\n"
        "def rewrite():\n    while True:\n        try:\n            open({grades!r}, 'w').write('carol,10')\n        except OSError:\n            time.sleep(0.01)\n"
        "threading.Thread(target=rewrite, daemon=True).start()\n" + STEP + "    return [x, y, theta]\n",
        "load", "loading your file raised RuntimeError at line 8: can't start new thread"),
    "spawn_rewriter": ("import subprocess\n" + STEP + "    subprocess.Popen(['sh', '-c', 'sleep 2; echo dave,10 > {grades}'])\n",
                       "raised", "raised PermissionError at line 3"),
    "read_passwd": (STEP + "    return open('/etc/passwd').read()\n", "raised", "FileNotFoundError at line 2"),
    "read_key": (STEP + "    return open({key!r}).read()\n", "raised", "FileNotFoundError at line 2"),
    "write_teacher": (STEP + "    open({teacher!r} + '/pwned.txt', 'w').write('x')\n", "raised", "at line 2"),
    "overwrite_classmate": (STEP + "    open({alice!r}, 'w').write('def step(*a):\\n    return [0, 0, 0]\\n')\n", "raised", "at line 2"),
    "read_classmate": ("import glob, os\n" + STEP + "    return open(glob.glob('/submission/../*/alice.py')[0] if glob.glob('/submission/../*/alice.py') else {alice!r}).read()\n",
                       "raised", "FileNotFoundError at line 3"),
    "seed_from_parent": ("import os\n" + STEP + "    argv = open(f'/proc/{{os.getppid() or 1}}/cmdline', 'rb').read().split(b'\\0')\n"
                         "    return int(argv[argv.index(b'--seed') + 1])\n", "raised", "raised FileNotFoundError at line 3"),
    "seed_anywhere": (
        "import os\n" + STEP + "    for pid in os.listdir('/proc'):\n        for part in ('cmdline', 'environ'):\n            try:\n"
        "                if b'{seed}' in open(f'/proc/{{pid}}/{{part}}', 'rb').read():\n                    return [0.0, 0.0, 0.0]\n"
        "            except OSError:\n                pass\n    raise LookupError('no seed in /proc')\n", "raised", "FileNotFoundError at line 3"),
    "import_reference": ("from sim.kinematics import integrate_arcs\n" + STEP + "    return [x, y, theta]\n", "forbidden", "import of sim.kinematics at line 1"),
    "import_module": ("import importlib\n" + STEP + "    return importlib.import_module('sim.kinematics').integrate_arcs\n", "forbidden", "import of sim.kinematics"),
    "import_by_path": ("import sys\nsys.path.insert(0, {root!r})\nimport sim.kinematics\n" + STEP + "    return [x, y, theta]\n",
                       "forbidden", "import of sim.kinematics at line 3"),
    "exec_source": (STEP + "    exec(open({root!r} + '/sim/kinematics/arc.py').read())\n", "raised", "FileNotFoundError at line 2"),
    "fork_bomb": ("import os\n" + STEP + "    while True:\n        os.fork()\n", "raised", "raised PermissionError at line 4"),
    "memory_bomb": (STEP + "    return bytearray(1 << 40)\n", "memory", "ran out of memory at line 2"),
    "memory_creep": ("import numpy\n" + STEP + "    hoard = []\n    while True:\n        hoard.append(numpy.zeros(50_000_000))\n", "memory", "ran out of memory at line 5"),
    "flood_stdout": (STEP + "    while True:\n        print('x' * 10000)\n", "output", "printed more than"),
    "flood_stderr": ("import sys\n" + STEP + "    while True:\n        sys.stderr.write('y' * 10000)\n", "output", "printed more than"),
    "kill_parent": ("import os, signal\n" + STEP + "    for pid in (os.getppid(), 1, -1):\n        try:\n            os.kill(pid, signal.SIGKILL)\n"
                    "        except OSError:\n            pass\n    return [x, y, theta]\n", "wrong", "("),
    "exit_at_load": ("import sys\nsys.exit(0)\n" + STEP + "    return [x, y, theta]\n", "load", "loading your file raised SystemExit at line 2"),
    "exit_in_step": ("import sys\n" + STEP + "    sys.exit(3)\n", "raised", "raised SystemExit at line 3"),
    "hard_exit": ("import os\n" + STEP + "    os._exit(0)\n", "crash", "ended the checking process"),
    "endless_loop": (STEP + "    while True:\n        pass\n", "timeout", "took longer than the time limit"),
    "sleeper": ("import time\n" + STEP + "    time.sleep(3600)\n", "timeout", "took longer than the time limit"),
    "network": ("import socket\n" + STEP + "    socket.create_connection(('93.184.216.34', 80), timeout=5)\n", "raised", "at line 3"),
    "huge_answer": ("import numpy\n" + STEP + "    return numpy.zeros(400_000)\n", "protocol", "the limit is"),
    "xml_breaker": (STEP + "    raise ValueError('\\x00\\x1b[2J\\ufffe' * 1000)\n", "raised", "raised ValueError at line 2"),
    "=2+5": (STEP + "    return [x, y, theta]\n", "wrong", "("),
    "raise_limits": ("import resource\n" + STEP + "    resource.setrlimit(resource.RLIMIT_AS, (-1, -1))\n", "raised", "raised ValueError at line 3"),
    # forged replies: the host reads data only
    "array_interface": (forge(json_body({"ok": {"__record__": ["R", {"__array_interface__": {"data": [0, False], "shape": [1 << 30], "typestr": "<f8",
                                                                                             "version": 3}}]}})), "protocol", "the answer could not be read"),
    "array_overread": (forge(json_body({"ok": {"__array__": ["float64", [1 << 20], [1.0]]}})), "protocol", "the answer could not be read"),
    "class_field": (forge(json_body({"ok": {"__record__": ["R", {"__class__": 1}]}})), "protocol", "the answer could not be read"),
    "long_error": (forge(json_body({"error": {"type": "E" * 300_000, "message": "m" * 300_000, "line": 1, "missing": "sim." + "x" * 300_000,
                                              "index": None, "value_error": False}})), "forbidden", "import of sim.xxx"),
    "deep_reply": (forge("b'{\"ok\": ' + b'[' * 300_000 + b']' * 300_000 + b'}'"), "protocol", "the answer could not be read"),
    # the kernel's shared state
    "keyring_writer": (SYSCALL + STEP + "    if call('add_key', b'user', b'ctsim-answers', b'10/10', 5, -4) < 0:\n"
                       "        raise PermissionError(ctypes.get_errno(), 'add_key refused')\n    return [x, y, theta]\n", "raised", "PermissionError at line 7: [Errno 1] add_key refused"),
    "keyring_reader": (SYSCALL + STEP + "    if call('request_key', b'user', b'ctsim-answers', None, 0) < 0:\n"
                       "        raise LookupError('no key from a classmate')\n    return [x, y, theta]\n", "raised", "LookupError at line 7: no key from a classmate"),
    "io_uring": (SYSCALL + STEP + "    params = (ctypes.c_uint32 * 30)(0, 2)\n    if call('io_uring_setup', 8, params) < 0:\n"
                 "        raise OSError(ctypes.get_errno(), 'io_uring refused')\n    return [x, y, theta]\n", "raised", "PermissionError at line 8: [Errno 1] io_uring refused"),
    # what is visible
    "mountinfo": (STEP + "    return open('/proc/self/mountinfo').read()\n", "raised", "FileNotFoundError at line 2"),
    "dist_packages": ("import sys\nsys.path += ['/usr/lib/python3/dist-packages', '/usr/local/lib/python3/dist-packages']\nimport yaml\n" + STEP
                      + "    return [x, y, theta]\n", "load", "ModuleNotFoundError at line 3"),
    # notebooks handed in instead of the file
    "bad_notebook": ("", "load", "source is not text"),
    "deep_notebook": ("", "load", "nested too deep"),
}
NOTEBOOKS = {
    "bad_notebook": json.dumps({"cells": [{"cell_type": "code", "metadata": {"tags": ["solution"]}, "source": 42}], "nbformat": 4}),
    "deep_notebook": "[" * 100_000 + "]" * 100_000,
}
"""Attacks handed in as notebooks (forward.ipynb in the student's folder)."""
ESCAPES, NEWLINE = "eve\x1b[2J\x1b]0;pwned\x07", "frank\n  10\u221510  mallory"
"""Honest students whose folder names hold a terminal escape sequence, and a newline that would
forge a line of the summary (U+2215, a slash that may be in a file name)."""
HONEST = {"alice": "reference", "bob": "euler", "erin": "swapped", "nina": "reference", "printer": "reference", ESCAPES: "reference",
          NEWLINE: "reference"}  # fmt: skip
HELPERS = {"nina": {"numpy.py": "raise ImportError('a numpy.py of my own, beside my solution')\n"}}
"""Files honest students hand in beside their solution (a helper that shadows a module the guest uses)."""
WRAPPED = {"nina": ("import numpy\n", ""), "printer": ("", "\n_step = step\ndef step(*a):\n    print('inputs', a)\n    return _step(*a)\n")}
"""Code before and after an honest student's solution: nina imports numpy (and gets the real one),
the printer prints every scenario's inputs (a hidden one's must stay in its row)."""


def _paths(root: Path) -> dict[str, str]:
    return {"key": str(root / "teacher" / "answer_key.py"), "grades": str(root / "teacher" / "grades" / "grades.csv"),
            "teacher": str(root / "teacher"), "alice": str(root / "subs" / "alice" / "forward.py"), "root": str(ROOT),
            "marker": str(root / "teacher" / "unpickled"), "seed": str(SEED)}  # fmt: skip


@dataclasses.dataclass
class Graded:
    root: Path
    reports: dict[str, object]
    alone: dict[str, object]
    rows: dict[str, dict[str, str]]
    files: dict[str, str]
    printed: str
    status: int


HANGS = ("endless_loop", "sleeper", "sleepy_start")
"""Attacks graded apart, with a short time limit: they never end, so any limit ends them. The rest
get a generous one: they must fail by what they do, never by a busy machine's clock."""
ATTACKS["sleepy_start"] = ("import time\ntime.sleep(4)\n" + STEP + "    time.sleep(3600)\n", "timeout", "took longer than the time limit")
HANGS_BUDGET = 8.0
"""Wall-clock seconds of a submission among the hangs: the sleepy start (4 s a start, then every call
overruns) spends it in two starts and is not started again for the third scenario."""


def _exercise_folder(root: Path, number: int, **changes) -> Path:
    """A copy of exercise 2 as a teacher's exercise `number`, its TOML's top keys changed (the CLI
    grades it as `ctsim lab --exercises DIR grade number ...`)."""
    folder = root / f"exercises{number}" / f"{number}_forward"
    shutil.copytree(exercise(2).folder, folder)
    toml = folder / "exercise.toml"
    changes |= {"number": number}
    lines = [line for line in toml.read_text().splitlines() if line.split("=")[0].strip() not in changes]
    toml.write_text("\n".join([f"{k} = {v}" for k, v in changes.items()] + lines) + "\n")  # top-level keys go before the first table
    return folder.parent


def _grade_by_cli(args: list[str]) -> tuple[list, str, int]:
    """`ctsim lab ... grade ...` as a teacher runs it: (its reports, what it printed, its exit status)."""
    from sim.lab import cli as lab_cli

    kept = {}

    def keeping(*a, **k):
        kept["reports"], written = grade(*a, **k)
        return kept["reports"], written

    printed = io.StringIO()
    with pytest.MonkeyPatch.context() as patch, contextlib.redirect_stdout(printed):
        patch.setattr(lab_cli, "grade", keeping)
        status = main(args)
    return kept["reports"], printed.getvalue(), status


@pytest.fixture(scope="module")
def graded(tmp_path_factory) -> Graded:
    root = tmp_path_factory.mktemp("class")
    paths = _paths(root)
    (root / "teacher").mkdir()
    Path(paths["key"]).write_text("KEY = 'the answers'\n")
    classes = {"subs": [*HONEST, *(a for a in ATTACKS if a not in HANGS)], "hangs": ["alice", *HANGS], "alone": list(HONEST)}
    for folder, names in classes.items():
        for name in names:
            (root / folder / name).mkdir(parents=True)
            if name in NOTEBOOKS:
                (root / folder / name / "forward.ipynb").write_text(NOTEBOOKS[name])
                continue
            before, after = WRAPPED.get(name, ("", ""))
            text = before + (SOLUTIONS / f"{HONEST[name]}.py").read_text() + after if name in HONEST else ATTACKS[name][0].format(**paths)
            (root / folder / name / "forward.py").write_text(text)
            for helper, code in HELPERS.get(name, {}).items():
                (root / folder / name / helper).write_text(code)
    (root / "subs" / "mallory").mkdir()
    os.symlink(paths["key"], root / "subs" / "mallory" / "forward.py")  # hands in the teacher's file
    files = {p.parent.name: p.read_text() for p in (root / "subs").glob("*/forward.py") if not p.is_symlink()}
    generous = str(_exercise_folder(root, 92, hidden=2, time_limit=30.0))
    common = ["--seed", str(SEED), "--jobs", "4"]
    alone, _, _ = _grade_by_cli(["lab", "--exercises", generous, "grade", "92", str(root / "alone"), "--out", str(root / "teacher" / "alone"), *common])
    reports, printed, status = _grade_by_cli(["lab", "--exercises", generous, "grade", "92", str(root / "subs"), "--out", str(root / "teacher" / "grades"), *common])
    short = str(_exercise_folder(root, 93, hidden=0, time_limit=1.0, budget=HANGS_BUDGET))
    hangs, _, _ = _grade_by_cli(["lab", "--exercises", short, "grade", "93", str(root / "hangs"), "--out", str(root / "teacher" / "hangs"), *common])
    rows = {r["student"].removeprefix("'"): r for r in csv.DictReader((root / "teacher" / "grades" / "grades.csv").open(encoding="utf-8"))}
    rows |= {r["student"]: r for r in csv.DictReader((root / "teacher" / "hangs" / "grades.csv").open(encoding="utf-8")) if r["student"] in HANGS}
    by_name = lambda found: {Path(r.file).parent.name: r for r in found}
    reports = by_name(reports) | {k: v for k, v in by_name(hangs).items() if k in HANGS}
    return Graded(root, reports, by_name(alone), rows, files, printed, status)


@pytest.mark.parametrize("name", sorted(ATTACKS))
def test_an_attack_fails_only_itself_with_a_clear_reason(graded: Graded, name: str) -> None:
    _, problem, text = ATTACKS[name]
    report = graded.reports[name]
    failed = [row for row in report.rows if not row.passed]
    assert failed and report.score < report.points
    assert failed[0].problem == problem, (failed[0].got, failed[0].hint)
    assert text in failed[0].got, failed[0].got
    assert failed[0].hint and "{" not in failed[0].hint
    assert graded.rows[name]["score"] == f"{round(report.score, 4):g}" and graded.rows[name]["isolation"] == "bubblewrap"


def test_the_honest_students_get_the_grades_they_get_alone(graded: Graded) -> None:
    for name in HONEST:
        mine, alone = graded.reports[name], graded.alone[name]
        assert [(r.passed, r.got) for r in mine.rows] == [(r.passed, r.got) for r in alone.rows]
    assert graded.reports["alice"].passed and graded.rows["alice"]["score"] == "10"


def test_nothing_outside_the_sandboxes_was_read_changed_or_left_running(graded: Graded) -> None:
    teacher = graded.root / "teacher"
    assert sorted(p.name for p in teacher.iterdir()) == ["alone", "answer_key.py", "grades", "hangs"]  # no pwned.txt, no unpickled
    assert {p.parent.name: p.read_text() for p in (graded.root / "subs").glob("*/forward.py") if not p.is_symlink()} == graded.files
    mine = str(graded.root).encode()
    for entry in Path("/proc").iterdir():
        try:
            assert mine not in (entry / "cmdline").read_bytes(), f"process {entry.name} of a submission still runs"
        except (OSError, ValueError):
            continue


def test_the_outputs_stay_readable_and_hold_each_student_once(graded: Graded) -> None:
    students = {*HONEST, *ATTACKS, "mallory"}
    assert set(graded.rows) == {sanitize.csv_cell(name).removeprefix("'") for name in students}
    suites = ET.parse(graded.root / "teacher" / "grades" / "junit.xml").getroot()
    assert sorted(s.get("name") for s in suites) == sorted(sanitize.xml_text(name) for name in students - set(HANGS))
    for name in students:
        folder = "hangs" if name in HANGS else "grades"
        results = json.loads((graded.root / "teacher" / folder / "gradescope" / name / "results.json").read_text())
        assert results["score"] == round(graded.reports[name].score, 4)
    assert "\n'=2+5," in (graded.root / "teacher" / "grades" / "grades.csv").read_text()  # no formula for a spreadsheet
    flood = json.loads((graded.root / "teacher" / "grades" / "gradescope" / "flood_stdout" / "results.json").read_text())
    assert "Your code printed:\nxxxx" in flood["output"] and len(flood["output"]) < 3000


def test_a_link_to_someone_else_s_file_is_not_graded(graded: Graded) -> None:
    row = graded.reports["mallory"].rows[0]
    assert row.problem == "link" and not row.passed and "KEY" not in row.got


def test_the_grader_exits_0_with_one_summary_line_per_student_and_no_escape_reaching_the_terminal(graded: Graded) -> None:
    assert graded.status == 0
    assert "\x1b" not in graded.printed and "\x07" not in graded.printed
    lines = graded.printed.splitlines()
    graded_lines = [line for line in lines if line.lstrip()[:1].isdigit() and "/10  " in line]
    assert len(graded_lines) == len(HONEST) + len(ATTACKS) - len(HANGS) + 1, lines  # mallory's link too
    assert any("frank\\x0a  10\u221510  mallory" in line for line in graded_lines)
    assert not any(line.startswith("  10\u2215") for line in lines)  # no forged line
    grades = (graded.root / "teacher" / "grades" / "grades.csv").read_text(encoding="utf-8")
    assert "\x1b" not in grades and "eve\\x1b[2J" in grades


def test_what_a_hidden_scenario_printed_reaches_only_its_row(graded: Graded) -> None:
    report = graded.reports["printer"]
    assert report.passed
    results = json.loads((graded.root / "teacher" / "grades" / "gradescope" / "printer" / "results.json").read_text())
    for row, test in zip(report.rows, results["tests"]):
        printed = row.output.splitlines()[0]
        assert printed.startswith("inputs (") and printed in test["output"]
        assert (printed in results["output"]) == (not row.hidden)
        assert test["visibility"] == ("after_published" if row.hidden else "visible")


def test_a_forged_long_error_is_cut_everywhere(graded: Graded) -> None:
    results = (graded.root / "teacher" / "grades" / "gradescope" / "long_error" / "results.json").read_text()
    suite = next(s for s in ET.parse(graded.root / "teacher" / "grades" / "junit.xml").getroot() if s.get("name") == "long_error")
    assert len(results) < 5000 and len(ET.tostring(suite)) < 5000


def test_a_submission_that_sleeps_at_every_start_is_ended_when_its_time_is_spent(graded: Graded) -> None:
    rows = graded.reports["sleepy_start"].rows
    assert rows[-1].problem == "budget" and f"{HANGS_BUDGET:g} s" in rows[-1].got


def test_a_numpy_of_the_student_s_own_beside_a_correct_solution_changes_nothing(graded: Graded) -> None:
    assert graded.reports["nina"].passed
