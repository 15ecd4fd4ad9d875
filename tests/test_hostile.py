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

from sim.cli import LOCK, main
from sim.experiments import Serial, load_results, sweep

STOPS_ONCE = '''
from pathlib import Path
from bots.commands import Twist

MARKER = Path(__file__).with_suffix(".stopped")

class StopsOnce:
    """Acts as Ctrl-C in its second step, the first time it runs."""
    def step(self, t, readings):
        if t > 0 and not MARKER.exists():
            MARKER.touch()
            raise KeyboardInterrupt
        return Twist(0.1, 0.0)
'''


def test_an_interrupted_sweep_keeps_no_row_of_the_run_it_cut_and_redoes_it_on_resume(tmp_path):
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
    assert "raised SystemExit: 3 at step 6" in capsys.readouterr().err
    assert summary_of(tmp_path / "out")["reason"] == "error"


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
        held.write("4242\n")
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

    monkeypatch.setattr("sim.cli.write_trajectories", full)
    assert run_cli("--controller", "square", "--out", str(tmp_path / "out")) == 1
    err = capsys.readouterr().err
    assert err == f"ctsim: error: writing the run's results into {tmp_path / 'out'}: No space left on device (written: summary.json)\n"
    assert summary_of(tmp_path / "out")["reason"] == "duration"


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
