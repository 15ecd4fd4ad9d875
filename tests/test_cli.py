"""The ctsim command line: help, a short run and its outputs, one-line errors, failing controllers,
Ctrl-C, world listing and checking, report, play offscreen."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sim.cli.entry import main

CTSIM = [sys.executable, "-m", "sim.cli"]
DRIVE = """
from bots.commands import WheelSpeeds

class Drive:
    def __init__(self, speed: float = 0.1):
        self.speed = speed

    def step(self, t, readings):
        return WheelSpeeds(self.speed, 1.2 * self.speed)
"""


@pytest.fixture()
def drive(tmp_path) -> str:
    path = tmp_path / "drive.py"
    path.write_text(DRIVE)
    return str(path)


def _ctsim(*args: str) -> subprocess.CompletedProcess:
    """The command line in a fresh process. No timeout of its own: a first run compiles numba's
    kernels for minutes on a loaded machine; pytest-timeout stops one that hangs."""
    return subprocess.run([*CTSIM, *args], capture_output=True, text=True)


def test_help():
    done = _ctsim("--help")
    assert done.returncode == 0 and "run" in done.stdout and "play" in done.stdout
    done = _ctsim("run", "--help")
    for option in ("--controller", "--param", "--duration", "--seed", "--out", "--robot", "--robots", "--until-goal", "--dt", "--live", "--no-report"):
        assert option in done.stdout
    assert _ctsim("--version").stdout.startswith("ctsim ")


def test_short_run_writes_everything(tmp_path, drive, capsys):
    out = tmp_path / "run"
    code = main(["run", "maze", "--controller", drive, "--param", "speed=0.15", "--duration", "1.5", "--seed", "3", "--out", str(out)])
    assert code == 0
    summary = json.loads((out / "summary.json").read_text())
    for key in ("ctsim_version", "world", "seed", "dt", "duration", "reason", "robots"):
        assert key in summary
    assert summary["seed"] == 3 and summary["reason"] == "duration"
    robot = summary["robots"][0]
    assert robot["controller"] == drive and robot["params"] == {"speed": 0.15}  # typed, not text
    assert robot["distance"] > 0.1 and set(robot["estimates"]) >= {"encoders"}
    for name in ["run.rrd", "truth.tum", "truth.csv", "trajectories.png", "errors.png"] + [f"{e}.tum" for e in robot["estimates"]]:
        assert (out / name).is_file(), name
    assert len((out / "truth.tum").read_text().splitlines()) == 1 + 151  # header + samples
    table = capsys.readouterr().out
    assert "encoders" in table and "run.rrd" in table


def test_several_robots_prefix_their_files(tmp_path, drive):
    out = tmp_path / "two"
    assert main(["run", "--controller", drive, "--robots", "2", "--duration", "0.3", "--out", str(out), "--no-report"]) == 0
    names = [r["name"] for r in json.loads((out / "summary.json").read_text())["robots"]]
    assert len(names) == 2 and all((out / f"{n}_truth.tum").is_file() for n in names)


def test_bad_world_file_is_one_line(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nbounds = [0, 0, 1\n')
    done = _ctsim("run", str(bad), "--duration", "0.1", "--out", str(tmp_path / "o"))
    assert done.returncode == 2
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"ctsim: error: {bad}:")


@pytest.mark.parametrize("args", [["--controller", "no_such_controller"], ["--robot", "no_such_robot"], ["--param", "nokey"]])
def test_user_errors_are_one_line(tmp_path, args):
    done = _ctsim("run", "--duration", "0.1", "--out", str(tmp_path / "o"), *args)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1


def test_controller_that_raises(tmp_path, capsys):
    broken = tmp_path / "broken.py"
    broken.write_text("from bots.commands import STOP\n\ndef controller(t, readings):\n    if t > 0.2:\n        raise RuntimeError('boom')\n    return STOP\n")
    out = tmp_path / "o"
    assert main(["run", "--controller", str(broken), "--duration", "1", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert str(broken) in err and "step 2" in err and "boom" in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reason"] == "error" and "boom" in summary["error"]
    assert (out / "run.rrd").is_file() and (out / "truth.tum").is_file()


@pytest.mark.parametrize(
    ("sig", "status", "reason", "size"),
    [
        (signal.SIGINT, 130, "interrupted", 1_000_000),
        (signal.SIGTERM, 143, "terminated", 1_000_000),
        (signal.SIGINT, 130, "interrupted", 0),  # while the recorder opens, before the first step
    ],
)
def test_a_signal_leaves_a_verified_recording(tmp_path, drive, sig, status, reason, size):
    """Ctrl-C and SIGTERM (a job scheduler, `timeout`) end a run alike: summary, trajectories and a
    recording that `rerun rrd verify` accepts."""
    out = tmp_path / "o"
    process = subprocess.Popen([*CTSIM, "run", "--controller", drive, "--duration", "3600", "--out", str(out), "--no-report"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 600  # start-up on a fresh, loaded machine compiles the kernels first
    recording = out / "run.rrd"
    while not (recording.exists() and recording.stat().st_size >= size) and time.monotonic() < deadline:
        time.sleep(0.1)  # until chunks are out (start-up alone writes ~0.3 MB): mid-run
    assert recording.exists(), "the run never started"
    process.send_signal(sig)  # honoured at the next step boundary, wherever the run is
    stdout, stderr = process.communicate(timeout=300)
    assert process.returncode == status, stderr
    assert reason in stderr and "Traceback" not in stderr
    assert json.loads((out / "summary.json").read_text())["reason"] == reason
    assert (out / "truth.tum").is_file()
    rerun = Path(sys.executable).with_name("rerun")
    verify = subprocess.run([str(rerun), "rrd", "verify", str(out / "run.rrd")], capture_output=True, text=True, timeout=60)
    assert verify.returncode == 0, verify.stderr


def test_worlds_check_and_controllers(tmp_path, capsys):
    assert main(["worlds"]) == 0
    assert "maze" in capsys.readouterr().out
    assert main(["check", "maze"]) == 0
    assert capsys.readouterr().out.startswith("OK")
    bad = tmp_path / "bad.toml"
    bad.write_text('name = "x"\nbounds = "wide"\n')
    assert main(["check", str(bad)]) == 2  # the same status as `run` on the same file
    assert capsys.readouterr().err.startswith(f"ctsim: error: {bad}:")
    assert main(["controllers"]) == 0


def test_report_redraws_a_run(tmp_path, drive, capsys):
    out = tmp_path / "o"
    assert main(["run", "--controller", drive, "--duration", "0.5", "--out", str(out), "--no-report"]) == 0
    assert not (out / "errors.png").exists()
    assert main(["report", str(out)]) == 0
    assert (out / "trajectories.png").stat().st_size > 10_000 and (out / "errors.png").is_file()
    assert main(["report", str(tmp_path)]) == 2


SPIN = """
from bots.commands import Twist


class Spin:
    def step(self, t, readings):
        return Twist(0.0, 1.0)  # on the spot: a car cannot
"""


def test_a_projected_command_is_in_the_summary_and_on_stderr(tmp_path, capsys):
    """The shipped car projects a turn on the spot to its tightest turn (DESIGN: reported, never
    silently done): the summary lists the kind of note with the number of steps, stderr says it."""
    spin = tmp_path / "spin.py"
    spin.write_text(SPIN)
    out = tmp_path / "car"
    assert main(["run", "chassis_yard", "--robot", "car", "--controller", f"{spin}:Spin", "--duration", "0.5", "--out", str(out), "--no-report"]) == 0
    (note,) = json.loads((out / "summary.json").read_text())["robots"][0]["notes"]
    assert "steering limits" in note["message"] and note["steps"] == 50
    assert "ctsim: note: car:" in capsys.readouterr().err


def _readme_wanderer(tmp_path: Path) -> tuple[Path, list[str]]:
    """The README's `wanderer.py` written where the README's command finds it, and that command."""
    readme = (Path(__file__).resolve().parent.parent / "README.md").read_text()
    code = readme.split("```python\n# wanderer.py\n", 1)[1].split("```", 1)[0]
    (tmp_path / "wanderer.py").write_text(code)
    command = next(line for line in readme.splitlines() if line.startswith("`ctsim run") and "wanderer.py:Wanderer" in line)
    return tmp_path / "wanderer.py", command.split("`")[1].split()[1:]


def test_the_readmes_wanderer_wanders_where_the_readme_runs_it(tmp_path, monkeypatch):
    """Every robot of the README's example command drives metres of floor in a minute without
    touching a wall (a naive one jitters against a wall: the IR reads a wall nearer than 8 cm as
    farther, and nan < 0.2 is False)."""
    path, args = _readme_wanderer(tmp_path)
    monkeypatch.chdir(tmp_path)
    out = tmp_path / "o"
    assert main([*args, "--duration", "60", "--out", str(out), "--no-report"]) == 0
    robots = json.loads((out / "summary.json").read_text())["robots"]
    assert len(robots) == 3
    for robot in robots:
        assert robot["collisions"] == 0 and robot["distance"] > 5.0  # 60 s at 0.15 m/s is 9 m, less the turns


def test_ctsim_worlds_shows_a_whole_first_sentence(capsys):
    from sim.cli.worlds import first_sentence

    assert first_sentence("A race, e.g. its first\nround: 0.24 m cells. Then more.") == "A race, e.g. its first round: 0.24 m cells."
    assert main(["worlds"]) == 0
    assert "(ctsim contest), e.g. its preliminary round" in " ".join(capsys.readouterr().out.split())


def test_a_run_s_ending_is_its_plain_name_in_every_file():
    """`Ending` is a str: summary.json, the sweep table and comparisons with the names hold its value."""
    from sim.run.ending import Ending

    assert json.dumps({"reason": Ending.GOAL}) == '{"reason": "goal"}' and f"{Ending.TERMINATED}" == "terminated"
    assert Ending("error") is Ending.ERROR and Ending.ERROR == "error"
    assert [e for e in Ending if e.signalled] == [Ending.INTERRUPTED, Ending.TERMINATED]


def test_the_api_and_the_command_line_describe_a_run_alike(tmp_path, drive):
    """summary.json has one home (`sim.analysis.summary`): `ctsim run` writes what the API's
    `Result.summary` gives for the same run, besides the options the command line adds."""
    from sim.analysis.summary import SCHEMA_VERSION, json_safe
    from sim.experiments import Bot, simulate

    out = tmp_path / "o"
    assert main(["run", "empty", "--controller", drive, "--duration", "0.5", "--noise", "none", "--seed", "3", "--out", str(out), "--no-report"]) == 0
    written = json.loads((out / "summary.json").read_text())
    given = json.loads(json.dumps(json_safe(simulate("empty", Bot(drive), duration=0.5, seed=3, noise="none").summary())))
    assert written["schema_version"] == given["schema_version"] == SCHEMA_VERSION
    for robot in written["robots"]:
        del robot["tum"]  # the files of the run folder, named after they are written
    assert {key: written[key] for key in given} == given
