"""A class with hostile students: `ctsim lab grade` on exercise 2 over honest submissions and
attacks on the grader. Each attack fails only itself, with a clear reason in the results; the
honest submissions get the grades they get when graded alone; nothing outside the sandboxes is
read, written or left running. One grading serves every test (module-scoped fixture)."""

from __future__ import annotations

import csv
import dataclasses
import json
import os
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from sim.lab import exercise
from sim.lab.grading import grade
from sim.sandbox import unavailable

pytestmark = pytest.mark.skipif(unavailable() is not None, reason=f"no OS sandbox here: {unavailable()}")

SOLUTIONS = Path(__file__).parent / "lab" / "ex2"
ROOT = Path(__file__).resolve().parents[1]
SEED = 24680  # any seed; a fixed one keeps the grading repeatable and lets the snoopers look for it
STEP = "def step(x, y, theta, v_left, v_right, track, dt):\n"
REPLIES = "import json, sys\nREPLIES = json.loads(sys.argv[1])['replies']\n"

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
                         "    return int(argv[argv.index(b'--seed') + 1])\n", "raised", "raised ValueError at line 4"),
    "seed_anywhere": (
        "import os\n" + STEP + "    for pid in os.listdir('/proc'):\n        for part in ('cmdline', 'environ'):\n            try:\n"
        "                if b'{seed}' in open(f'/proc/{{pid}}/{{part}}', 'rb').read():\n                    return [0.0, 0.0, 0.0]\n"
        "            except OSError:\n                pass\n    raise LookupError('no seed in /proc')\n", "raised", "LookupError at line 10: no seed in /proc"),
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
    "exit_at_load": ("import sys\nsys.exit(0)\n", "load", "loading your file raised SystemExit at line 2"),
    "exit_in_step": ("import sys\n" + STEP + "    sys.exit(3)\n", "raised", "raised SystemExit at line 3"),
    "hard_exit": ("import os\n" + STEP + "    os._exit(0)\n", "crash", "ended the checking process"),
    "endless_loop": (STEP + "    while True:\n        pass\n", "timeout", "took longer than the time limit"),
    "sleeper": ("import time\n" + STEP + "    time.sleep(3600)\n", "timeout", "took longer than the time limit"),
    "network": ("import socket\n" + STEP + "    socket.create_connection(('93.184.216.34', 80), timeout=5)\n", "raised", "at line 3"),
    "huge_answer": ("import numpy\n" + STEP + "    return numpy.zeros(400_000)\n", "protocol", "the limit is"),
    "xml_breaker": (STEP + "    raise ValueError('\\x00\\x1b[2J\\ufffe' * 1000)\n", "raised", "raised ValueError at line 2"),
    "=2+5": (STEP + "    return [x, y, theta]\n", "wrong", "("),
    "raise_limits": ("import resource\n" + STEP + "    resource.setrlimit(resource.RLIMIT_AS, (-1, -1))\n", "raised", "raised ValueError at line 3"),
}
HONEST = {"alice": "reference", "bob": "euler", "erin": "swapped"}


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


HANGS = ("endless_loop", "sleeper")
"""Attacks graded apart, with a short time limit: they never end, so any limit ends them. The rest
get a generous one: they must fail by what they do, never by a busy machine's clock."""


@pytest.fixture(scope="module")
def graded(tmp_path_factory) -> Graded:
    root = tmp_path_factory.mktemp("class")
    paths = _paths(root)
    (root / "teacher").mkdir()
    Path(paths["key"]).write_text("KEY = 'the answers'\n")
    classes = {"subs": [*HONEST, *(a for a in ATTACKS if a not in HANGS)], "hangs": ["alice", *HANGS], "alone": list(HONEST)}
    for folder, names in classes.items():
        for name in names:
            text = (SOLUTIONS / f"{HONEST[name]}.py").read_text() if name in HONEST else ATTACKS[name][0].format(**paths)
            (root / folder / name).mkdir(parents=True)
            (root / folder / name / "forward.py").write_text(text)
    (root / "subs" / "mallory").mkdir()
    os.symlink(paths["key"], root / "subs" / "mallory" / "forward.py")  # hands in the teacher's file
    files = {p.parent.name: p.read_text() for p in (root / "subs").glob("*/forward.py") if not p.is_symlink()}
    generous = dataclasses.replace(exercise(2), hidden=2, time_limit=30.0)
    alone, _ = grade(generous, root / "alone", root / "teacher" / "alone", seed=SEED, jobs=4)
    reports, _ = grade(generous, root / "subs", root / "teacher" / "grades", seed=SEED, jobs=4)
    hangs, _ = grade(dataclasses.replace(exercise(2), hidden=0, time_limit=1.0), root / "hangs", root / "teacher" / "hangs", seed=SEED, jobs=4)
    rows = {r["student"].removeprefix("'"): r for r in csv.DictReader((root / "teacher" / "grades" / "grades.csv").open(encoding="utf-8"))}
    rows |= {r["student"]: r for r in csv.DictReader((root / "teacher" / "hangs" / "grades.csv").open(encoding="utf-8")) if r["student"] in HANGS}
    by_name = lambda found: {Path(r.file).parent.name: r for r in found}  # noqa: E731
    return Graded(root, by_name(reports) | {k: v for k, v in by_name(hangs).items() if k in HANGS}, by_name(alone), rows, files)


@pytest.mark.parametrize("name", sorted(ATTACKS))
def test_an_attack_fails_only_itself_with_a_clear_reason(graded: Graded, name: str) -> None:
    _, problem, text = ATTACKS[name]
    report = graded.reports[name]
    failed = [row for row in report.rows if not row.passed]
    assert failed and report.score < report.points
    assert failed[0].problem == problem, (failed[0].got, failed[0].hint)
    assert text in failed[0].got, failed[0].got
    assert failed[0].hint and "{" not in failed[0].hint
    assert graded.rows[name]["score"] == f"{round(report.score, 1):g}" and graded.rows[name]["isolation"] == "bubblewrap"


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
    assert set(graded.rows) == {*HONEST, *ATTACKS, "mallory"}
    suites = ET.parse(graded.root / "teacher" / "grades" / "junit.xml").getroot()
    assert sorted(s.get("name") for s in suites) == sorted(set(graded.rows) - set(HANGS))
    for name in graded.rows:
        folder = "hangs" if name in HANGS else "grades"
        results = json.loads((graded.root / "teacher" / folder / "gradescope" / name / "results.json").read_text())
        assert results["score"] == round(graded.reports[name].score, 4)
    assert "\n'=2+5," in (graded.root / "teacher" / "grades" / "grades.csv").read_text()  # no formula for a spreadsheet
    flood = json.loads((graded.root / "teacher" / "grades" / "gradescope" / "flood_stdout" / "results.json").read_text())
    assert "Your code printed:\nxxxx" in flood["output"] and len(flood["output"]) < 3000


def test_a_link_to_someone_else_s_file_is_not_graded(graded: Graded) -> None:
    row = graded.reports["mallory"].rows[0]
    assert row.problem == "link" and not row.passed and "KEY" not in row.got
