"""User code that reaches for what ctsim keeps: controllers that make the recorded readings
writeable again, estimators that hang, answer differently each time they are read or leave with
sys.exit, controllers that leave while being made or reset. Each ends as the user's error in one
line, and nothing it did reaches the recorded data."""

from __future__ import annotations

import json
import signal
import textwrap
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from sim.cli.entry import main

CODE = '''
import sys, time
import numpy as np
from bots.commands import Twist

class Rewrites:
    """Makes every way at its readings writeable that numpy offers, and writes 99 through each."""
    def step(self, t, readings):
        for array in (readings.ir_distance, readings.ir_raw, readings.encoder_ticks):
            for way in (array, array.base, getattr(array.base, "base", None)):
                if isinstance(way, np.ndarray):
                    try:
                        way.flags.writeable = True
                        way[...] = 99
                    except ValueError:
                        pass
        return Twist(0.1, 0.0)

class LeavesWhenMade:
    def __init__(self):
        sys.exit(3)
    def step(self, t, readings):
        return Twist(0.0, 0.0)

class LeavesOnReset:
    def reset(self, robot):
        sys.exit(4)
    def step(self, t, readings):
        return Twist(0.0, 0.0)

class PatchesAClassMethod:
    def step(self, t, readings):
        if t > 0.05:
            from sim.world.physics import World
            World.step = lambda self, commands: 1 / 0
        return Twist(0.1, 0.0)

class Hangs:
    name = "hangs"
    def reset(self, robot, pose):
        self.pose, self.steps = np.array(pose, dtype=float), 0
    def update(self, readings):
        self.steps += 1
        if self.steps == 5:
            time.sleep(1000)

class Terminated:
    """Sends itself SIGTERM (as `timeout` or systemd would) and then blocks in its update."""
    name = "terminated"
    def reset(self, robot, pose):
        self.pose, self.steps = np.array(pose, dtype=float), 0
    def update(self, readings):
        self.steps += 1
        if self.steps == 5:
            import os, signal
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1000)

class Fickle:
    """A pose that is fine when first read after each update and NaN when read again."""
    name = "fickle"
    def reset(self, robot, pose):
        self._pose, self.reads = np.array(pose, dtype=float), 0
    def update(self, readings):
        self.reads = 0
    @property
    def pose(self):
        self.reads += 1
        return self._pose if self.reads == 1 else np.full(3, np.nan)

class Leaves:
    name = "leaves"
    def reset(self, robot, pose):
        self.pose = np.array(pose, dtype=float)
    def update(self, readings):
        sys.exit(3)
'''


@pytest.fixture()
def code(tmp_path):
    path = tmp_path / "hostile.py"
    path.write_text(textwrap.dedent(CODE))
    return path


def run(*argv: str) -> int:
    return main(["run", "empty", "--duration", "0.2", "--no-report", *argv])


def test_no_flag_or_base_makes_the_recorded_readings_writeable(code, tmp_path):
    assert run("--controller", f"{code}:Rewrites", "--noise", "none", "--out", str(tmp_path / "out")) == 0
    table = pq.read_table(tmp_path / "out" / "run.parquet").to_pandas()
    readings = table[[c for c in table.columns if ".ir_distance." in c or ".ir_raw." in c or ".encoder" in c]]
    assert len(readings.columns) and not (readings == 99).any().any()


def test_sys_exit_while_a_controller_is_made_or_reset_is_the_users_error_in_one_line(code, tmp_path, capsys):
    for name, said in (("LeavesWhenMade", "making it called sys.exit(3)"), ("LeavesOnReset", "the controller's reset called sys.exit(4)")):
        assert run("--controller", f"{code}:{name}", "--out", str(tmp_path / name)) == 2
        err = capsys.readouterr().err
        assert err.startswith("ctsim: error: ") and err.count("\n") == 1 and said in err, err


@pytest.mark.skipif(not hasattr(signal, "setitimer"), reason="the step timer is POSIX")
def test_an_estimator_that_hangs_meets_the_step_time_limit(code, tmp_path, capsys):
    out = tmp_path / "out"
    assert run("--controller", "idle", "--estimator", f"{code}:Hangs", "--step-timeout", "0.4", "--out", str(out)) == 1
    assert "estimator 'hangs' of ctbot took longer than the step time limit of 0.4 s at step 4" in capsys.readouterr().err
    assert json.loads((out / "summary.json").read_text())["reason"] == "error"


def test_an_estimator_value_is_read_once_so_what_is_checked_is_what_is_logged(code, tmp_path, capsys):
    out = tmp_path / "out"
    assert run("--controller", "idle", "--estimator", f"{code}:Fickle", "--out", str(out)) == 0
    rows = np.loadtxt(out / "fickle.tum", comments="#", ndmin=2)
    assert len(rows) == 21 and np.isfinite(rows).all()


def test_sys_exit_in_an_estimator_ends_the_run_as_the_users_error_with_its_files(code, tmp_path, capsys):
    out = tmp_path / "out"
    assert run("--controller", "idle", "--estimator", f"{code}:Leaves", "--out", str(out)) == 1
    assert "estimator 'leaves' of ctbot raised SystemExit: 3 at step 0" in capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reason"] == "error" and "SystemExit" in summary["error"] and (out / "truth.tum").is_file()


def test_a_patched_class_method_is_the_controllers_error_not_ctsims(code, tmp_path, capsys):
    from sim.world.physics import World

    step = World.step
    try:
        assert run("--controller", f"{code}:PatchesAClassMethod", "--out", str(tmp_path / "out")) == 1
    finally:
        World.step = step
    err = capsys.readouterr().err
    assert f"put its own code into ctsim's ({code}:" in err and "ZeroDivisionError" in err and "Traceback" not in err
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["reason"] == "error"


@pytest.mark.skipif(not Path("/proc/self/statm").exists(), reason="the address-space check reads /proc (Linux)")
def test_a_run_too_long_for_the_address_space_limit_is_refused_in_one_line(tmp_path):
    """Under `ulimit -v 6 GiB` a run of 1e5 s (4 GiB of samples) used to die of SIGABRT inside
    the recorder; now it is refused before it starts (exit 2), its folder left empty."""
    import resource
    import subprocess
    import sys

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (6 << 30, resource.RLIM_INFINITY))

    out = tmp_path / "long"
    done = subprocess.run([sys.executable, "-m", "sim.cli", "run", "empty", "--controller", "idle", "--duration", "1e5", "--no-report", "--out", str(out)],
                          capture_output=True, text=True, timeout=600, preexec_fn=limit, cwd=Path(__file__).resolve().parents[1])  # fmt: skip
    assert done.returncode == 2, done.stderr[-2000:]
    assert done.stderr.startswith("ctsim: error: the run needs about ") and done.stderr.count("\n") == 1 and "ulimit -v" in done.stderr
    assert not any(out.iterdir())  # (its lock file removed as the command ended)


@pytest.mark.skipif(not hasattr(signal, "setitimer"), reason="the step clock is POSIX")
def test_the_first_sigterm_inside_an_estimator_ends_the_run_at_once(code, tmp_path, capsys):
    out = tmp_path / "out"
    assert run("--controller", "idle", "--estimator", f"{code}:Terminated", "--out", str(out)) == 143
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reason"] == "terminated" and (out / "truth.tum").is_file()
