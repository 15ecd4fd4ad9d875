"""Whole contests (sim.contest, `ctsim contest`) in a two-lane world with short games: the command
line's outputs and errors, a contest killed mid-way and resumed ends as one never interrupted,
the same game is the same bit for bit in any process, a firmware through the bridge races Python
controllers, and a hostile student submission changes no other game's result."""

from __future__ import annotations

import csv
import hashlib
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sim.cli.entry import main
from sim.contest import Settings, conduct, parse
from sim.contest.game import GameJob, play
from sim.contest.ranking import ranking
from sim.contest.store import Store
from sim.experiments.engines import Processes, Serial
from sim.folder_lock import LOCK

ROOT = Path(__file__).resolve().parents[1]
LANES = ROOT / "tests" / "data" / "contest_lanes.toml"
DRIVER = """
from bots.commands import Twist

class Driver:
    def __init__(self, speed: float = {speed}):
        self.speed = speed
    def step(self, t, readings):
        return Twist(self.speed, 0.0)
"""
COMPARED = ("level", "number", "entry1", "entry2", "state", "winner", "reason", "verdict", "time", "arrival1", "arrival2",
            "distance1", "distance2", "out1", "out2", "error", "digest")  # fmt: skip
"""The columns of a game that must come out the same (not its wall time or when it was written)."""


@pytest.fixture
def lanes(tmp_path) -> Path:
    world = tmp_path / "lanes.toml"
    world.write_text(LANES.read_text())
    (tmp_path / "driver.py").write_text(DRIVER.format(speed=0.2))
    return world


def drivers(folder: Path, *speeds: float) -> list[str]:
    """Entries `v<speed>=driver.py,speed=<speed>`: straight drivers, faster ones arrive first."""
    return [f"v{str(s).replace('.', '')}={folder / 'driver.py'},speed={s}" for s in speeds]


def games(path: Path) -> list[tuple]:
    with sqlite3.connect(path) as db:
        return db.execute(f"SELECT {', '.join(COMPARED)} FROM games ORDER BY level, number").fetchall()


def test_a_contest_from_the_command_line_writes_bracket_ranking_and_database(lanes, tmp_path, capsys):
    out = tmp_path / "contest"
    entries = drivers(tmp_path, 0.1, 0.3, 0.2, 0.15, 0.25)
    code = main(["contest", str(lanes), *entries, "--time-limit", "6", "--engine", "serial", "--noise", "none", "--out", str(out)])  # straight drivers in exact lanes
    printed = capsys.readouterr().out
    assert code == 0 and not (out / LOCK).exists()  # (the contest's lock removed as it ended)
    with (out / "ranking.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [r["entry"] for r in rows] == ["v03", "v025", "v02", "v015", "v01"]  # the fastest wins every race
    assert [r["place"] for r in rows] == ["1", "2", "3", "4", "5"] and rows[0]["out in"] == "-"
    assert "v03" in printed and "bracket.html" in printed
    with sqlite3.connect(out / "contest.sqlite") as db:  # the contest keeps its noise among its settings
        assert db.execute("SELECT value FROM settings WHERE key = 'noise'").fetchone() == ("none",)
    page = (out / "bracket.html").read_text()
    recordings = sorted(p.relative_to(out).as_posix() for p in (out / "games").glob("*.rrd"))
    assert len(recordings) == 5 + 5  # five alone, four knockout games and the game for third place
    assert all(f'href="{r}"' in page for r in recordings)
    assert (out / "bracket.png").stat().st_size > 10_000
    store = Store(out)
    assert store.seeds() == {2: 1, 5: 2, 3: 3, 4: 4, 1: 5}  # by arrival in the preliminary round
    final = store.games("level = 1")[0]
    assert final.reason == "goal" and final.winner == 2 and final.arrival1 == pytest.approx(1.3 / 0.3, abs=0.011)  # one step
    again = main(["contest", str(lanes), *entries, "--time-limit", "6", "--engine", "serial", "--noise", "none", "--out", str(out)])
    assert again == 0 and "v03" in capsys.readouterr().out  # a finished contest is only reported again


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (["maze", "solve_maze", "nonsense_controller"], "unknown controller 'nonsense_controller'"),
        (["maze", "a=solve_maze", "a=solve_maze,hand=left"], "two entries are called 'a'"),
        (["empty", "solve_maze"], "no goal for the robot from start slot"),
        (["ONE_START", "solve_maze"], "needs 2 start slot(s), this one has 1"),
        (["contest", "firmware:/no/such/ct-Bot"], "no such firmware file"),
        (["contest", "solve_maze,speed_m_s"], "expected KEY=VALUE"),
        (["contest", f"firmware:{ROOT / 'README.md'}"], "not executable"),
    ],
)
def test_mistakes_are_one_line_and_exit_2(arguments, message, tmp_path, capsys):
    if arguments[0] == "ONE_START":
        (tmp_path / "one.toml").write_text("[[start]]\nposition = [0.5, 0.5]\n[[goal]]\nbox = [1, 1, 1.2, 1.2]\n")
        arguments = [str(tmp_path / "one.toml"), *arguments[1:]]
    assert main(["contest", *arguments]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


def test_another_contest_in_the_same_folder_is_refused(lanes, tmp_path, capsys):
    out = tmp_path / "c"
    assert main(["contest", str(lanes), *drivers(tmp_path, 0.3, 0.2), "--time-limit", "5", "--engine", "serial", "--no-record", "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["contest", str(lanes), *drivers(tmp_path, 0.3, 0.25), "--time-limit", "5", "--engine", "serial", "--out", str(out)]) == 2
    assert "holds another contest (entries differ)" in capsys.readouterr().err
    assert main(["contest", str(lanes), *drivers(tmp_path, 0.3, 0.2), "--time-limit", "5", "--engine", "serial", "--noise", "none", "--out", str(out)]) == 2
    assert "holds another contest (noise differ)" in capsys.readouterr().err  # realistic by default, as every run; --noise is a setting


def test_resume_after_a_kill_ends_as_an_uninterrupted_contest(lanes, tmp_path):
    """Killed (SIGKILL, the whole process group) once four games are in the database, the same
    command again plays only the rest; the games equal those of a contest never interrupted."""
    entries = drivers(tmp_path, 0.1, 0.3, 0.2, 0.15, 0.25, 0.12)
    command = [sys.executable, "-m", "sim.cli", "contest", str(lanes), *entries, "--time-limit", "6", "--engine", "serial", "--no-record"]
    killed = tmp_path / "killed"
    process = subprocess.Popen([*command, "--out", str(killed)], cwd=ROOT, start_new_session=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    database = killed / "contest.sqlite"
    while process.poll() is None:
        done = 0
        if database.exists():
            try:
                with sqlite3.connect(database) as db:
                    done = db.execute("SELECT count(*) FROM games WHERE state = 'done'").fetchone()[0]
            except sqlite3.OperationalError:  # not created yet, or being written
                pass
        if done >= 4:
            os.killpg(process.pid, signal.SIGKILL)
            break
        time.sleep(0.05)
    process.wait()
    assert process.returncode == -signal.SIGKILL, "the contest ended before it could be killed"
    part = games(database)
    assert 4 <= sum(row[COMPARED.index("state")] == "done" for row in part) < 12
    subprocess.run([*command, "--out", str(killed)], cwd=ROOT, check=True, capture_output=True)
    subprocess.run([*command, "--out", str(tmp_path / "whole")], cwd=ROOT, check=True, capture_output=True)
    resumed, whole = games(database), games(tmp_path / "whole" / "contest.sqlite")
    assert resumed == whole and len(whole) == 6 + 6  # six alone, two first-round games, semis, final, third place
    assert all(row[COMPARED.index("state")] == "done" for row in whole)


def test_the_same_game_is_the_same_bit_for_bit_in_any_process(lanes, tmp_path):
    job = GameJob(2, 1, tuple(parse(drivers(tmp_path, 0.2, 0.15))), str(lanes), 4.0, 7, 0.01, None)
    here = play(job)
    (_, there), (_, again) = Processes(2).imap(play, [job, job])
    assert here["digest"] == there["digest"] == again["digest"]
    assert here["sides"] == there["sides"] and here["verdict"] == there["verdict"]
    exact = [play(GameJob(2, 1, job.entries, job.world, 4.0, seed, 0.01, None, noise="none")) for seed in (7, 8)]
    assert exact[0]["sides"] == exact[1]["sides"] and exact[0]["digest"] == exact[1]["digest"]  # no noise: the seed changes nothing ...
    assert play(GameJob(2, 1, job.entries, job.world, 4.0, 8, 0.01, None))["digest"] != here["digest"]  # ... with the default noise it does
    noisy = [play(GameJob(2, 1, tuple(parse(["a=wander", "b=wander"])), "contest", 3.0, seed, 0.01, None))["digest"] for seed in (1, 1)]
    assert noisy[0] == noisy[1]  # ... and a wanderer among walls is the same run for the same seed


def test_a_firmware_races_python_controllers_through_the_bridge(lanes, tmp_path):
    """The fake firmware (tests/fake_firmware.py, started like the real one with -t ADDRESS, its
    port fixed at 10001) drives at RC5 key 3's 75 units = 131.8 mm/s from two steps after the key
    (c't-Sim's lock-step); it reaches its goal 1.3 m ahead before a driver at 0.1 m/s."""
    fake = ROOT / "tests" / "fake_firmware.py"
    entries = tuple(parse([f"fw=firmware:{fake},rc5=0.1:3", *drivers(tmp_path, 0.1)]))
    outcome = play(GameJob(2, 1, entries, str(lanes), 14.0, 0, 0.01, str(tmp_path / "race.rrd"), noise="none"))  # (a closed form: exact wheels)
    assert "crash" not in outcome, outcome.get("crash")
    speed = 75 * 151 / 60 * 178.1283 / 255 / 1000  # m/s: ACT_MOT units through c't-Sim's mapping
    assert outcome["verdict"]["winner"] == 0 and outcome["verdict"]["reason"] == "goal"
    assert outcome["sides"][0]["arrival"] == pytest.approx(0.1 + 0.02 + 1.3 / speed, abs=0.021)  # two steps of rounding
    from test_bridge import read_recording

    events = [str(v) for column in read_recording(tmp_path / "race.rrd")["/events"].values() for v in column]
    assert any("verdict: fw reached its goal" in text for text in events)  # the judge's word is in the recording too


def test_a_hostile_submission_changes_no_other_games_result(lanes, tmp_path):
    """A class of four; mallory's file, on loading and at every step, tries to overwrite the contest
    database and a classmate's file, kill its parent, start a process, read another submission,
    and prints without end. The sandbox lets none of it through: the classmates' files and the
    database are intact, every game without mallory gives what it gives replayed on its own, and
    mallory's own games are judged (a flood of output fails its robot)."""
    from sim.sandbox import unavailable

    if (reason := unavailable()) is not None:
        pytest.skip(f"no sandbox here: {reason}")
    out, class_dir = tmp_path / "contest", tmp_path / "class"
    class_dir.mkdir()
    for name, speed in (("alice", 0.3), ("bob", 0.25), ("carol", 0.2)):
        (class_dir / f"{name}.py").write_text(DRIVER.format(speed=speed))
    (class_dir / "mallory.py").write_text(HOSTILE.format(database=out / "contest.sqlite", alice=class_dir / "alice.py"))
    before = {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in class_dir.iterdir()}
    entries = parse([str(class_dir)])
    settings = Settings(str(lanes), str(lanes), 6.0)
    store = conduct(settings, entries, out, Serial(), record=False, say=lambda line: None)
    assert {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in class_dir.iterdir()} == before
    assert store.db.execute("PRAGMA integrity_check").fetchone() == ("ok",)
    names = [e.name for e in store.entries()]
    mallory = names.index("mallory") + 1
    seeds = store.seeds()
    for game in store.games("state = 'done'"):
        if mallory in (game.entry1, game.entry2):
            continue
        sides = [game.entry1] if game.level == -1 else sorted((game.entry1, game.entry2), key=seeds.get)
        replay = play(GameJob(game.level, game.number, tuple(entries[e - 1] for e in sides), str(lanes), 6.0, 0, 0.01, None))
        assert replay["digest"] == game.digest
    assert [row["entry"] for row in ranking(store)][:3] == ["alice", "bob", "carol"]
    (prelim,) = store.games("level = -1 AND entry1 = ?", mallory)
    assert prelim.reason == "failure" and "printed more than" in prelim.error


HOSTILE = '''
import os
from bots.commands import Twist

def attack():
    for attempt in (
        lambda: open("{database}", "r+b").write(b"winner" * 100),
        lambda: open("{alice}", "w").write("raise SystemExit"),
        lambda: open("{alice}").read(),
        lambda: os.kill(os.getppid(), 9),
        lambda: os.kill(1, 9),
        lambda: os.fork(),
    ):
        try:
            attempt()
        except BaseException:
            pass

attack()

class Driver:
    def step(self, t, readings):
        attack()
        print("x" * 100_000)
        return Twist(0.35, 0.0)
'''


def test_a_contest_on_dask_ends_as_on_local_processes(lanes, tmp_path):
    """The sweep's engine option: the same games on a Dask LocalCluster (a process of its own), the same database."""
    from sim.experiments.engines import Dask

    entries = parse(drivers(tmp_path, 0.3, 0.2))
    settings = Settings(str(lanes), str(lanes), 6.0)
    conduct(settings, entries, tmp_path / "local", Serial(), record=False, say=lambda line: None)
    runner = Dask(workers=1)
    try:
        conduct(settings, entries, tmp_path / "dask", runner, record=False, say=lambda line: None)
    finally:
        runner.close()
    assert games(tmp_path / "dask" / "contest.sqlite") == games(tmp_path / "local" / "contest.sqlite")
