"""Hostile input, one test per case of issue #26: files, options, controllers, output folders and
signals that once crashed, hung or lost a run now end in one clear line and a documented status,
with what was simulated kept. Each test builds its hostile file or command itself."""

from __future__ import annotations

import errno
import json
import os
import subprocess
from pathlib import Path

import pytest

from sim.cli.entry import main
from sim.experiments import Serial, load_results, sweep
from sim.folder_lock import LOCK

STOPS_ONCE = '''
import signal
from pathlib import Path
from bots.commands import Twist

MARKER = Path(__file__).with_suffix(".stopped")

class StopsOnce:
    """Sends its process Ctrl-C in its second step, the first time it runs."""
    def step(self, t, readings):
        if t > 0 and not MARKER.exists():
            MARKER.touch()
            signal.raise_signal(signal.SIGINT)
        return Twist(0.1, 0.0)
'''


def test_an_interrupted_sweep_keeps_no_row_of_the_run_it_cut_and_redoes_it_on_resume(tmp_path, ctrl_c):
    controller = tmp_path / "stops.py"
    controller.write_text(STOPS_ONCE)
    spec = {"base": {"duration": 0.05, "world": "empty", "controller": f"{controller}:StopsOnce"}, "axes": {"seed": [0, 1]}}
    with pytest.raises(KeyboardInterrupt):
        sweep(spec, tmp_path / "out", Serial(), progress=False)
    assert len(load_results(tmp_path / "out")) == 0  # the cut run is not a row
    table = sweep(spec, tmp_path / "out", Serial(), progress=False)
    assert len(table) == 2 and (table["reason"] == "duration").all()


def test_a_sweep_of_a_million_runs_is_refused_at_once_with_the_limit(tmp_path, capsys):
    spec = tmp_path / "big.toml"
    spec.write_text("[axes]\nseed = [" + ", ".join(map(str, range(1000))) + "]\n\"params.speed_m_s\" = [" + ", ".join(f"{0.1 + i * 1e-4:.4f}" for i in range(1000)) + "]\n")
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "1,000,000 runs" in err and "100,000" in err and err.count("\n") == 1


# --- runs: options, controllers, output folders, signals ----------------------------------------

CONTROLLERS = '''
import os
import signal
import sys
import time
from pathlib import Path
from bots.commands import Twist

class Blocks:
    """Blocks in its sixth step, as a controller waiting on a socket that never answers."""
    def step(self, t, readings):
        if t > 0.05:
            time.sleep(1000)
        return Twist(0.1, 0.0)

class Exits:
    def step(self, t, readings):
        if t > 0.05:
            sys.exit(3)
        return Twist(0.1, 0.0)

class TermThenBlocks:
    """Gets SIGTERM (a job scheduler) while it blocks."""
    def step(self, t, readings):
        if t > 0.05:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1000)
        return Twist(0.1, 0.0)

class Odd:
    """Raises what no controller should: a BaseException that is not Ctrl-C."""
    def step(self, t, readings):
        if t > 0.05:
            raise GeneratorExit("odd")
        return Twist(0.1, 0.0)

class CtrlCTwice:
    """Ctrl-C pressed twice, the second time while the run is being written."""
    def step(self, t, readings):
        if t > 0.05 and not hasattr(self, "pressed"):
            self.pressed = True
            os.kill(os.getpid(), signal.SIGINT)
            os.kill(os.getpid(), signal.SIGINT)
        return Twist(0.1, 0.0)
'''


@pytest.fixture()
def controllers(tmp_path) -> Path:
    path = tmp_path / "hostile.py"
    path.write_text(CONTROLLERS)
    return path


def summary_of(folder: Path) -> dict:
    """summary.json read by a strict parser (NaN and infinities refused)."""
    def refuse(constant):
        raise ValueError(f"not strict JSON: {constant}")

    return json.loads((folder / "summary.json").read_text(), parse_constant=refuse)


def status(argv: list[str]) -> int:
    """The exit status of `ctsim ARGV`, run in this process (argparse's refusals exit)."""
    try:
        return main(argv)
    except SystemExit as done:
        return done.code


def run_cli(*args: str) -> int:
    return status(["run", "empty", "--duration", "1", "--no-report", *args])


def test_a_blocking_controller_ends_the_run_at_its_step_time_limit(controllers, tmp_path, capsys):
    assert run_cli("--controller", f"{controllers}:Blocks", "--step-timeout", "0.4", "--out", str(tmp_path / "out")) == 1
    assert "took longer than the step time limit of 0.4 s at step 6" in capsys.readouterr().err
    summary = summary_of(tmp_path / "out")
    assert summary["reason"] == "error" and summary["time"] == pytest.approx(0.06)  # every step before it kept
    assert (tmp_path / "out" / "truth.tum").read_text().count("\n") == 1 + 7  # header, samples at 0 .. 0.06 s


def test_sys_exit_in_a_controller_is_the_controllers_error(controllers, tmp_path, capsys):
    assert run_cli("--controller", f"{controllers}:Exits", "--out", str(tmp_path / "out")) == 1
    assert "called sys.exit(3) at step 6" in capsys.readouterr().err
    assert summary_of(tmp_path / "out")["reason"] == "error"


def test_any_exception_of_a_controller_is_its_error(controllers, tmp_path, capsys):
    assert run_cli("--controller", f"{controllers}:Odd", "--out", str(tmp_path / "out")) == 1
    assert "raised GeneratorExit: odd at step 6" in capsys.readouterr().err


def test_sys_exit_while_a_controller_file_loads_is_one_line(tmp_path, capsys):
    path = tmp_path / "leaves.py"
    path.write_text("import sys\nsys.exit(4)\n")
    assert run_cli("--controller", str(path), "--out", str(tmp_path / "out")) == 2
    err = one_error_line(capsys)
    assert "leaves.py" in err and "SystemExit: 4" in err


def test_sigterm_reaches_a_run_whose_controller_blocks(controllers, tmp_path):
    assert run_cli("--controller", f"{controllers}:TermThenBlocks", "--out", str(tmp_path / "out")) == 143
    summary = summary_of(tmp_path / "out")
    assert summary["reason"] == "terminated" and summary["time"] == pytest.approx(0.06)


def test_ctrl_c_twice_keeps_the_summary_and_the_trajectories(controllers, tmp_path):
    assert main(["run", "empty", "--duration", "1", "--controller", f"{controllers}:CtrlCTwice", "--out", str(tmp_path / "out")]) == 130
    assert summary_of(tmp_path / "out")["reason"] == "interrupted"
    assert (tmp_path / "out" / "truth.tum").read_text().count("\n") == 1 + 7  # header, samples at 0 .. 0.06 s
    assert not list((tmp_path / "out").glob("*.png"))  # figures skipped after the signal


@pytest.mark.parametrize(
    "options, message",
    [
        (["--out", ""], "--out: expected a folder, got an empty name"),
        (["--robots", "1000000000"], "1000000000 robots, but the world has room for 3"),  # empty: three start slots
        (["--robots", "99999999999999999999"], "room for 3"),
        (["--dt", "1e-300"], "expected a step between 0.0001 and 1 s"),
        (["--dt", "100"], "expected a step between 0.0001 and 1 s"),
        (["--dt", "0.5", "--duration", "0.1"], "less than half a step"),
    ],
)
def test_impossible_run_options_are_refused_with_the_limit(options, message, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert status(["run", "empty", "--no-report", *options]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not any(tmp_path.iterdir())  # nothing was written, not even into the current folder


def test_a_folder_in_use_by_another_run_is_refused(tmp_path, capsys):
    import fcntl

    (tmp_path / "out").mkdir()
    with open(tmp_path / "out" / LOCK, "w") as held:  # another run holds it
        held.write("4242 run\n")
        held.flush()
        fcntl.flock(held, fcntl.LOCK_EX)
        assert run_cli("--controller", "square", "--out", str(tmp_path / "out")) == 2
    assert "in use by another ctsim run (process 4242)" in capsys.readouterr().err
    assert run_cli("--controller", "square", "--out", str(tmp_path / "out")) == 0  # free again


def test_a_full_temporary_folder_is_said_before_the_run(tmp_path, capsys, monkeypatch):
    def full(descriptor, offset, size):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "posix_fallocate", full)
    assert run_cli("--controller", "square", "--out", str(tmp_path / "out")) == 2
    err = capsys.readouterr().err
    assert "trajectories need" in err and "TMPDIR" in err and err.count("\n") == 1
    assert not (tmp_path / "out" / "summary.json").exists()


def test_a_disk_full_while_writing_ends_with_one_line_and_the_summary_kept(tmp_path, capsys, monkeypatch):
    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr("sim.cli.output.write_trajectories", full)
    assert run_cli("--controller", "square", "--out", str(tmp_path / "out")) == 1
    err = capsys.readouterr().err
    assert err == f"ctsim: error: writing the run's results into {tmp_path / 'out'}: No space left on device (written: run.rrd, summary.json)\n"
    assert summary_of(tmp_path / "out")["reason"] == "duration"
    assert sorted(p.name for p in (tmp_path / "out").iterdir() if not p.name.startswith(".")) == ["run.rrd", "summary.json"]  # the list is what is there


@pytest.fixture()
def small_disk(tmp_path):
    """A 300 KiB file system (root only: mount a tmpfs)."""
    folder = tmp_path / "small"
    folder.mkdir()
    if os.geteuid() != 0 or subprocess.run(["mount", "-t", "tmpfs", "-o", "size=300k", "tmpfs", str(folder)], capture_output=True).returncode:
        pytest.skip("needs root to mount a small tmpfs")
    yield folder
    subprocess.run(["umount", str(folder)], check=False)


def test_a_run_onto_a_300_kib_disk_keeps_its_summary_and_says_so_in_one_line(small_disk, capsys):
    status_ = status(["run", "maze", "--controller", "solve_maze", "--duration", "20", "--no-report", "--out", str(small_disk / "run")])
    assert status_ == 1
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("ctsim")]
    assert len(err) == 1 and "No space left on device" in err[0]
    summary = summary_of(small_disk / "run")
    assert summary["reason"] == "duration" and summary["time"] == 20.0


# --- files: hangs, robot files, worlds that check OK but are not ---------------------------------

BILLION_LAUGHS = ('<?xml version="1.0"?>\n<!DOCTYPE world [\n<!ENTITY a "aaaaaaaaaa">\n'
                  + "".join(f'<!ENTITY {chr(98 + i)} "' + f"&{chr(97 + i)};" * 10 + '">\n' for i in range(9))
                  + "]>\n<world><parcours><line>&j;</line></parcours></world>\n")


def one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    assert err.startswith("ctsim: error: ") and err.count("\n") == 1, err
    return err


@pytest.mark.parametrize("command", ["check", "run"])
def test_a_kilobyte_of_nested_xml_entities_is_refused_at_once(tmp_path, capsys, command):
    path = tmp_path / "laughs.xml"
    path.write_text(BILLION_LAUGHS)
    assert len(BILLION_LAUGHS) < 1024
    assert status([command, str(path)] + (["--out", str(tmp_path / "out")] if command == "run" else [])) == 2
    assert f"{path}:3: XML refused: EntitiesForbidden" in one_error_line(capsys)


def test_a_long_xml_text_is_read_in_linear_time(tmp_path, capsys):
    """200,000 text pieces (one per entity-free character reference) once took quadratic time."""
    path = tmp_path / "long.xml"
    path.write_text("<world><parcours><line>" + "&#46;" * 200_000 + "</line></parcours></world>")
    assert status(["check", str(path)]) == 2
    assert "more than the 250,000 tiles" not in one_error_line(capsys)  # 200,000 tiles fit, but no start


@pytest.mark.parametrize(("suffix", "command"), [("world.toml", "check"), ("robot.toml", "run"), ("sweep.toml", "sweep")])
def test_deeply_nested_toml_is_one_line_not_a_recursion_error(tmp_path, capsys, suffix, command):
    path = tmp_path / suffix
    path.write_text("x = " + "[" * 5000 + "]" * 5000 + "\n")
    argv = {"check": ["check", str(path)], "run": ["run", "empty", "--robot", str(path), "--out", str(tmp_path / "o")],
            "sweep": ["sweep", str(path), "--out", str(tmp_path / "o")]}[command]
    assert status(argv) == 2
    assert f"{path}" in one_error_line(capsys)


ROBOT = 'name = "b"\nwheel_diameter = 0.0567\ntrack_width = 0.0972\nbody_radius = 0.06\n'


@pytest.mark.parametrize(
    ("text", "line", "message"),
    [
        (ROBOT + "mass = -1\n", 5, "mass: must be a number (kg) at least 0.001 and at most 1,000, not -1"),
        (ROBOT + "mass = nan\n", 5, "mass: must be a number (kg) at least 0.001"),
        (ROBOT + "mass = 0\n", 5, "mass: must be a number (kg) at least 0.001"),
        (ROBOT + 'mass = "x"\n', 5, "mass: must be a number (kg)"),
        (ROBOT + "[encoders]\nticks_per_rev = 0\n", 6, "[encoders]: ticks_per_rev: must be a whole number (ticks) at least 1"),
        (ROBOT + "[encoders]\nticks_per_rev = -60\n", 6, "ticks_per_rev: must be a whole number (ticks) at least 1"),
        (ROBOT + '[[light]]\nname = "l"\nposition = [0.03, 0]\nreach = 0\n', 8, "[[light]] #1: reach: must be a number (m) greater than 0"),
        (ROBOT + '[[ir]]\nname = "i"\nposition = [0.05, 0]\nside = "up"\n', 8, "[[ir]] #1: side: must be one of 'left', 'right', not 'up'"),
        (ROBOT + '[[ir]]\nname = "i"\nposition = [0.05]\n', 7, "[[ir]] #1: position: must be a list of 2 numbers (m)"),
        (ROBOT + '[[ir]]\nname = "i"\nposition = [50, 0]\n', 7, "at least -2 and at most 2, not [50, 0]"),
        (ROBOT.replace("0.0567", "true"), 2, "wheel_diameter: must be a number (m) at least 0.001 and at most 2, not true"),
        (ROBOT + "[motor]\nmax_wheel_speed = -15.8\n", 6, "[motor]: max_wheel_speed: must be a number (rad/s) greater than 0"),
        (ROBOT + "[motor]\ntime_constant = -0.1\n", 6, "[motor]: time_constant: must be a number (s) at least 0"),
        (ROBOT.replace("body_radius = 0.06", "body_radius = 20"), 4, "body_radius: must be a number (m) at least 0.001 and at most 2, not 20"),
        (ROBOT + "skid = [1, 2, 3]\n", 5, "skid: must be a list of 2 numbers (m)"),
    ],
)
def test_robot_file_mistakes_are_one_line_with_file_line_and_key(tmp_path, capsys, text, line, message):
    path = tmp_path / "bot.toml"
    path.write_text(text)
    assert status(["run", "empty", "--robot", str(path), "--out", str(tmp_path / "out")]) == 2
    err = one_error_line(capsys)
    assert f"{path}:{line}: " in err and message in err, err
    assert not (tmp_path / "out").exists()


def test_a_robot_file_that_is_not_utf8_names_file_and_line(tmp_path, capsys):
    path = tmp_path / "bot.toml"
    path.write_bytes(ROBOT.encode() + b'# caf\xe9\n')
    assert status(["run", "empty", "--robot", str(path)]) == 2
    assert f"{path}:5: not UTF-8 text: byte 0xe9" in one_error_line(capsys)


@pytest.mark.parametrize("setting", ["encoders.ticks_per_rev=0", "mass=-1", "ir.side=up", "light.reach=0"])
def test_robot_set_values_meet_the_same_schema(tmp_path, capsys, setting):
    assert status(["run", "empty", "--robot-set", setting, "--out", str(tmp_path / "out")]) == 2
    assert f"ctsim: error: {setting.split('=')[0]}: must be" in one_error_line(capsys)


CROWD = "bounds = [0, 0, 1, 1]\n" + "".join(f"[[start]]\nposition = [{0.45 + 0.01 * (k % 10):.2f}, {0.45 + 0.01 * (k // 10):.2f}]\nslot = {k + 1}\n" for k in range(50))


def test_fifty_overlapping_starts_are_named_by_check_and_refused_by_run(tmp_path, capsys):
    path = tmp_path / "crowd.toml"
    path.write_text(CROWD)
    assert status(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert out.count("warning: the starts of slots") == 10  # the first ten pairs (of 1,225)
    assert "are 0.010 m apart, closer than two c't-Bots need (0.12 m)" in out
    assert status(["run", str(path), "--robots", "50", "--controller", "idle", "--out", str(tmp_path / "out")]) == 2
    last = capsys.readouterr().err.splitlines()[-1]  # after the same ten warnings
    assert last == "ctsim: error: ctbot and ctbot1 start 0.010 m apart, closer than their bodies allow (0.120 m): give them starts farther apart"


@pytest.mark.parametrize("text", ["bounds = [0, 0, 1, 1]\n", "bounds = [0, 0, 1, 1]\n[[goal]]\nbox = [0.1, 0.1, 0.2, 0.2]\n"])
def test_a_world_without_room_for_a_robot_fails_check(tmp_path, capsys, text):
    path = tmp_path / "w.toml"
    path.write_text(text)
    assert status(["check", str(path)]) == 2
    assert "no start pose" in one_error_line(capsys)


def test_a_parcours_without_a_start_fails_check(tmp_path, capsys):
    path = tmp_path / "w.xml"
    path.write_text("<world><parcours><line>#####</line><line>#.Z.#</line><line>#####</line></parcours></world>")
    assert status(["check", str(path)]) == 2
    assert "room for 0 robots" in one_error_line(capsys)


def test_bridge_with_more_firmwares_than_starts_is_refused_before_listening(tmp_path, capsys):
    assert status(["bridge", "empty", "--robots", "50", "--port", "0", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "50 firmware bot(s) and 0 Python robot(s), but the world has room for 3" in err and "listening" not in err
