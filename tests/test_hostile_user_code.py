"""User code that reaches for what ctsim keeps: controllers that make the recorded readings
writeable again, estimators that hang, answer differently each time they are read or leave with
sys.exit, controllers and estimators that fail or leave while being made or reset, controllers that patch
methods of ctsim's and numpy's classes. Each ends as the user's error in one
line, and nothing it did reaches the recorded data."""

from __future__ import annotations

import json
import os
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

class FailsOnReset:
    def reset(self, robot):
        raise RuntimeError("no wheels today")
    def step(self, t, readings):
        return Twist(0.0, 0.0)

class HangsOnReset:
    def reset(self, robot):
        time.sleep(1000)
    def step(self, t, readings):
        return Twist(0.0, 0.0)

class EstimatorLeavesWhenMade:
    def __init__(self):
        sys.exit(5)
    def reset(self, robot, pose):
        pass
    def update(self, readings):
        pass

class EstimatorLeavesOnReset:
    name = "leaves_on_reset"
    def reset(self, robot, pose):
        sys.exit(6)
    def update(self, readings):
        pass

class PatchesAClassMethod:
    def step(self, t, readings):
        if t > 0.05:
            from sim.world.physics import World
            World.step = lambda self, commands: 1 / 0
        return Twist(0.1, 0.0)

class PatchesWithABuiltin:
    """No frame of this file runs when the run fails: only the Guard can tell."""
    def step(self, t, readings):
        if t > 0.05:
            from sim.world.physics import World
            World.poses_view = len
        return Twist(0.1, 0.0)

class PatchesOnReset:
    def reset(self, robot):
        from sim.world.physics import World
        World.step = lambda self, commands: 1 / 0
    def step(self, t, readings):
        return Twist(0.1, 0.0)

class PatchesWhenMade:
    """Replaces a method of ctsim's World in its constructor, before the run has started."""
    def __init__(self):
        from sim.world.physics import World
        World.step = lambda self, commands: 1 / 0
    def step(self, t, readings):
        return Twist(0.1, 0.0)

class PatchesJsonWhenMade:
    """Replaces what ctsim writes summary.json with, in its constructor."""
    def __init__(self):
        import json
        json.dumps = lambda *args, **kwargs: "{}"
    def step(self, t, readings):
        return Twist(0.1, 0.0)

class PatchesQuietly:
    """Changes what ctsim does not call in this run: the run goes on, and the change is undone."""
    def step(self, t, readings):
        from sim.run.samples import Samples
        Samples.added = lambda self: 1
        np.lib.NumpyVersion.__lt__ = lambda self, other: True
        return Twist(0.1, 0.0)

class StepProperty:
    @property
    def step(self):
        raise RuntimeError("no step today")

class StatusOfItsOwn:
    """A `status` that is not a behaviour's Status: not a way to say the robot is done."""
    status = "running"
    def step(self, t, readings):
        return Twist(0.1, 0.0)

class ShadowsStdoutWrite:
    def step(self, t, readings):
        sys.stdout.write = None
        return Twist(0.1, 0.0)

class NameRaises:
    @property
    def name(self):
        raise RuntimeError("no name")
    def reset(self, robot, pose):
        self.pose = np.array(pose, dtype=float)
    def update(self, readings):
        pass

class SlowCovariance:
    name = "slow"
    def reset(self, robot, pose):
        self.pose = np.array(pose, dtype=float)
    def update(self, readings):
        pass
    @property
    def covariance(self):
        time.sleep(1000)

class PlantsAFolder:
    """Makes a folder where the run will write truth.tum (its folder named in CTSIM_TEST_OUT)."""
    def step(self, t, readings):
        import os, pathlib
        (pathlib.Path(os.environ["CTSIM_TEST_OUT"]) / "truth.tum").mkdir(exist_ok=True)
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

class RaisesInterrupt:
    """Raises KeyboardInterrupt itself, no signal sent: its error, not the user's Ctrl-C."""
    def step(self, t, readings):
        if t > 0.05:
            raise KeyboardInterrupt
        return Twist(0.1, 0.0)

class InterruptsWhenMade:
    def __init__(self):
        raise KeyboardInterrupt("in my constructor")
    def step(self, t, readings):
        return Twist(0.0, 0.0)

class InterruptsOnReset:
    def reset(self, robot):
        raise KeyboardInterrupt
    def step(self, t, readings):
        return Twist(0.0, 0.0)

class EstimatorInterrupts:
    name = "interrupts"
    def reset(self, robot, pose):
        self.pose = np.array(pose, dtype=float)
    def update(self, readings):
        raise KeyboardInterrupt

class SendsCtrlC:
    """Sends its own process SIGINT, as a terminal's Ctrl-C does: an interrupt (130), not an error."""
    def step(self, t, readings):
        if t > 0.05:
            import signal
            signal.raise_signal(signal.SIGINT)
        return Twist(0.1, 0.0)
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


@pytest.mark.parametrize(("option", "name", "said"), [
    ("--controller", "LeavesWhenMade", "making it called sys.exit(3) ({code}:"),
    ("--estimator", "EstimatorLeavesWhenMade", "making it called sys.exit(5) ({code}:"),
])  # fmt: skip
def test_user_code_that_leaves_while_it_is_made_fails_in_one_line_before_the_folder_is(option, name, said, code, tmp_path, capsys):
    """exit 1 (the user's code failed, not their options); nothing ran, so no folder."""
    assert run(option, f"{code}:{name}", "--out", str(tmp_path / "out")) == 1
    err = capsys.readouterr().err
    assert err.startswith("ctsim: error: ") and err.count("\n") == 1 and said.format(code=code) in err, err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("argv", "said"), [
    (("--controller", "{code}:LeavesOnReset"), "controller '{code}:LeavesOnReset' of ctbot called sys.exit(4) in its reset at t = 0.00 s ({code}:"),
    (("--controller", "{code}:FailsOnReset"), "of ctbot raised RuntimeError: no wheels today in its reset at t = 0.00 s ({code}:"),
    (("--controller", "idle", "--estimator", "{code}:EstimatorLeavesOnReset"), "estimator 'leaves_on_reset' of ctbot called sys.exit(6) in its reset"),
    (("--controller", "{code}:HangsOnReset", "--step-timeout", "0.4"), "of ctbot took longer than the step time limit of 0.4 s in its reset"),
])  # fmt: skip
def test_user_code_that_fails_in_its_reset_ends_the_run_as_its_error_with_every_file(argv, said, code, tmp_path, capsys):
    """The run had started (its folder and a summary saying 'running'): it ends at t = 0 as the
    user's error, exit 1, its files written and the summary saying how it ended."""
    out = tmp_path / "out"
    assert run(*(a.format(code=code) for a in argv), "--out", str(out)) == 1
    assert said.format(code=code) in capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reason"] == "error" and said.format(code=code) in summary["error"]
    assert {"run.rrd", "run.parquet", "truth.tum", "encoders.tum", "report.html"} <= {p.name for p in out.iterdir()}


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
    assert "estimator 'leaves' of ctbot called sys.exit(3) at step 0" in capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reason"] == "error" and "sys.exit(3)" in summary["error"] and (out / "truth.tum").is_file()


@pytest.mark.parametrize(("cls", "said"), [
    ("PatchesAClassMethod", "replaced sim.world.physics.World.step, and the run failed with ZeroDivisionError"),
    ("PatchesWithABuiltin", "replaced sim.world.physics.World.poses_view, and the run failed with TypeError"),
    ("PatchesOnReset", "replaced sim.world.physics.World.step, and the run failed with ZeroDivisionError: division by zero at t = 0.00 s"),
])  # fmt: skip
def test_a_patched_class_method_is_the_controllers_error_and_is_put_back(cls, said, code, tmp_path, capsys):
    from sim.world.physics import World

    methods = World.step, World.poses_view
    assert run("--controller", f"{code}:{cls}", "--out", str(tmp_path / "out")) == 1
    err = capsys.readouterr().err
    assert f"controller '{code}:{cls}' of ctbot {said}" in err and "Traceback" not in err, err
    assert json.loads((tmp_path / "out" / "summary.json").read_text())["reason"] == "error"
    assert (World.step, World.poses_view) == methods  # (the next run in this process has ctsim's own)


def test_methods_a_controller_adds_or_replaces_where_the_run_does_not_call_them_are_put_back(code, tmp_path, capsys):
    from sim.run.samples import Samples

    before = np.lib.NumpyVersion.__lt__
    assert run("--controller", f"{code}:PatchesQuietly", "--out", str(tmp_path / "out")) == 0
    assert "the controller replaced numpy.lib.NumpyVersion.__lt__, sim.run.samples.Samples.added; ctsim put them back" in capsys.readouterr().err
    assert np.lib.NumpyVersion.__lt__ is before and not hasattr(Samples, "added")


@pytest.mark.parametrize(("cls", "replaced"), [("PatchesJsonWhenMade", "json.dumps"), ("PatchesWhenMade", "sim.world.physics.World.step")])
def test_what_a_constructor_replaces_is_put_back_before_anything_is_written_or_run(cls, replaced, code, tmp_path, capsys):
    """Made before the run (and its guards): put back as soon as it is made (`sim.guards.making`),
    so summary.json is written with ctsim's json and the run steps ctsim's World."""
    from sim.world.physics import World

    before = json.dumps, World.step
    assert run("--controller", f"{code}:{cls}", "--out", str(tmp_path / "out")) == 0
    assert f"ctsim: note: a controller or estimator replaced {replaced} while it was made; ctsim put it back" in capsys.readouterr().err
    assert (json.dumps, World.step) == before and json.loads((tmp_path / "out" / "summary.json").read_text())["reason"] == "duration"


LONG_RUN = """
import resource, sys
from sim.analysis import export
from sim.run import samples
from sim.views.recording import recorder
from sim.cli.entry import main

samples.HEADROOM = 0  # (the check's allowance for the recorder: the limit below is this process's own peak and a margin)
samples.BLOCK = export.FILE_ROWS = recorder.CHUNK = 1000  # (what is read and sent at a time: reached by the short runs already)

def peak():
    return int(dict(line.split(":", 1) for line in open("/proc/self/status"))["VmPeak"].split()[0]) * 1024

out = sys.argv[1]
command = ["run", "empty", "--controller", "idle", "--robots", "3", "--no-report", "--duration"]
for k in range(2):  # (the second: as much address space as such a run takes)
    assert main([*command, "15", "--out", f"{out}-{k}"]) == 0
resource.setrlimit(resource.RLIMIT_AS, (peak() + (48 << 20), resource.RLIM_INFINITY))
sys.exit(main([*command, "400", "--out", out]))
"""


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="the process's peak address space is read from /proc (Linux)")
def test_a_long_run_finishes_under_an_address_space_limit_its_samples_would_not_fit(tmp_path):
    """Under `ulimit -v 6 GiB` a run of 1e5 s (4 GiB of samples) was refused (before that it died
    of SIGABRT inside the recorder): its samples were one mapping of the whole run. They go to a
    file a window at a time now: a 400 s run of three robots (52 MB of samples) finishes within
    48 MiB of address space above what a 15 s run took, and writes every file (the mapping of the
    whole run ran out of memory there). glibc's arenas capped so that threads add none unseen."""
    import subprocess
    import sys

    out = tmp_path / "long"
    done = subprocess.run([sys.executable, "-c", LONG_RUN, str(out)], capture_output=True, text=True, timeout=600,
                          cwd=Path(__file__).resolve().parents[1], env={**os.environ, "MALLOC_ARENA_MAX": "2"})  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reason"] == "duration" and summary["time"] == pytest.approx(400.0)
    assert len((out / "ctbot2_truth.tum").read_text().splitlines()) == 40001 + 1  # (a header line, then every sample)
    assert pq.read_metadata(out / "run.parquet").num_rows == 40001 and (out / "run.rrd").stat().st_size > 0


@pytest.mark.skipif(not hasattr(signal, "setitimer"), reason="the step clock is POSIX")
def test_the_first_sigterm_inside_an_estimator_ends_the_run_at_once(code, tmp_path, capsys):
    out = tmp_path / "out"
    assert run("--controller", "idle", "--estimator", f"{code}:Terminated", "--out", str(out)) == 143
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reason"] == "terminated" and (out / "truth.tum").is_file()


def test_a_step_property_that_raises_is_the_users_error_in_one_line(code, tmp_path, capsys):
    assert run("--controller", f"{code}:StepProperty", "--out", str(tmp_path / "out")) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"asking it for its step raised RuntimeError: no step today ({code}:" in err


def test_a_status_that_is_not_a_behaviours_does_not_end_the_run(code, tmp_path):
    out = tmp_path / "out"
    assert run("--controller", f"{code}:StatusOfItsOwn", "--out", str(out)) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reason"] == "duration" and summary["time"] == pytest.approx(0.2)


def test_a_method_of_stdout_shadowed_by_a_controller_is_put_back(code, tmp_path, capsys):
    assert run("--controller", f"{code}:ShadowsStdoutWrite", "--out", str(tmp_path / "out")) == 0
    out, err = capsys.readouterr()
    assert "wrote:" in out and "Traceback" not in err and "(or a method of theirs); ctsim put them back" in err


def test_an_estimator_whose_name_cannot_be_read_is_named_by_its_class(code, tmp_path):
    out = tmp_path / "out"
    assert run("--controller", "idle", "--estimator", f"{code}:NameRaises", "--out", str(out)) == 0
    assert (out / "NameRaises.tum").is_file()


@pytest.mark.skipif(not hasattr(signal, "setitimer"), reason="the step timer is POSIX")
def test_a_timeout_names_the_line_of_the_users_code_it_ended_not_ctsims(code, tmp_path, capsys):
    assert run("--controller", "idle", "--estimator", f"{code}:SlowCovariance", "--step-timeout", "0.4", "--out", str(tmp_path / "out")) == 1
    err = capsys.readouterr().err
    assert f"estimator 'slow' of ctbot took longer than the step time limit of 0.4 s at step 0 (t = 0.00 s) ({code}:" in err


@pytest.mark.parametrize("kind", ["pipe", "device", "folder"])
def test_a_controller_or_estimator_file_that_is_not_a_regular_file_is_refused_without_reading_it(kind, tmp_path, capsys):
    import os

    path = tmp_path / "mine.py"
    if kind == "pipe":
        os.mkfifo(path)
    elif kind == "device":
        path.symlink_to("/dev/zero")
    else:
        path.mkdir()
    for option in ("--controller", "--estimator"):
        assert run(option, str(path), "--out", str(tmp_path / "out")) == 2
        assert f"{path}: not a regular file (a pipe, device or folder)" in capsys.readouterr().err


def test_a_step_time_limit_too_short_for_its_timer_is_refused(tmp_path, capsys):
    """At 1e-9 s the step timer's ticks came faster than their handler ran: the run never ended."""
    from sim.experiments import simulate
    from sim.run.ending import RunError

    with pytest.raises(SystemExit) as refused:  # (argparse's refusal)
        run("--controller", "idle", "--step-timeout", "1e-9", "--out", str(tmp_path / "out"))
    assert refused.value.code == 2 and "argument --step-timeout: must be a number (s) at least 0.05" in capsys.readouterr().err
    with pytest.raises(RunError, match="at least 0.05 s"):
        simulate("empty", duration=0.1, step_timeout=1e-9)


def test_a_folder_planted_at_a_files_name_during_the_run_fails_the_writing_not_the_options(code, tmp_path, monkeypatch, capsys):
    """exit 1 (the run ran; its writing failed), one line naming the folder, the summary kept."""
    out = tmp_path / "out"
    monkeypatch.setenv("CTSIM_TEST_OUT", str(out))
    assert run("--controller", f"{code}:PlantsAFolder", "--out", str(out)) == 1
    err = capsys.readouterr().err
    assert f"{out}/truth.tum is a folder: ctsim cannot write its file there" in err
    assert json.loads((out / "summary.json").read_text())["reason"] == "duration"
    # the other trajectories are written all the same, and the line names every file written and no other
    written = err.rsplit("(written: ", 1)[1].rstrip(")\n").split(", ")
    assert sorted(written) == sorted(p.name for p in out.iterdir() if p.is_file() and not p.name.startswith("."))
    assert {"run.rrd", "summary.json", "run.parquet", "encoders.tum", "truth.csv"} <= set(written)


def test_the_list_of_files_a_run_wrote_is_every_file_in_its_folder(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["run", "empty", "--duration", "0.2", "--out", str(out)]) == 0
    listed = capsys.readouterr().out.split("wrote:\n", 1)[1].split()
    assert sorted(listed) == sorted(str(p) for p in out.iterdir() if p.is_file() and not p.name.startswith("."))


@pytest.mark.parametrize(("argv", "status", "said"), [
    (("--controller", "{code}:RaisesInterrupt"), 1, "controller '{code}:RaisesInterrupt' of ctbot raised KeyboardInterrupt at step 6 (t = 0.06 s) ({code}:"),
    (("--controller", "{code}:InterruptsOnReset"), 1, "controller '{code}:InterruptsOnReset' of ctbot raised KeyboardInterrupt in its reset at t = 0.00 s ({code}:"),
    (("--controller", "idle", "--estimator", "{code}:EstimatorInterrupts"), 1, "estimator 'interrupts' of ctbot raised KeyboardInterrupt at step 0 (t = 0.00 s) ({code}:"),
    (("--controller", "{code}:SendsCtrlC"), 130, "interrupted at t = 0.0"),
])  # fmt: skip
def test_a_keyboard_interrupt_user_code_raises_itself_is_its_error_and_ctrl_c_stays_an_interrupt(argv, status, said, code, tmp_path, capsys):
    """Told apart by whether a signal came (`sim.interrupts`): the code's own KeyboardInterrupt
    ends the run as its error naming its file and line (exit 1), a SIGINT as Ctrl-C (130); both
    with every file written and the summary saying how the run ended."""
    out = tmp_path / "out"
    assert run(*(a.format(code=code) for a in argv), "--out", str(out)) == status
    assert said.format(code=code) in capsys.readouterr().err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reason"] == ("error" if status == 1 else "interrupted") and said.format(code=code) in summary["error"]
    assert {"run.parquet", "truth.tum"} <= {p.name for p in out.iterdir()}


def test_a_keyboard_interrupt_a_constructor_raises_is_its_error_in_one_line(code, tmp_path, capsys):
    assert run("--controller", f"{code}:InterruptsWhenMade", "--out", str(tmp_path / "out")) == 1
    err = capsys.readouterr().err
    assert err.startswith("ctsim: error: ") and err.count("\n") == 1, err
    assert "making it raised KeyboardInterrupt: in my constructor" in err and f"({code}:" in err


def test_simulate_puts_back_what_a_constructor_replaced_before_the_run(code):
    from sim.experiments import Bot, simulate
    from sim.world.physics import World

    before = World.step
    result = simulate("empty", Bot(f"{code}:PatchesWhenMade"), duration=0.1)
    assert result.reason == "duration" and World.step is before
    assert result.raw.notes[0] == "a controller or estimator replaced sim.world.physics.World.step while it was made; ctsim put it back"


def test_a_disk_error_writing_the_samples_mid_run_ends_it_keeping_every_sample_before(tmp_path, monkeypatch, capsys):
    """The samples' file fails (a disk error, ENOSPC) when the third window of 100 rows goes to
    it: the run ends there in one line (exit 1), and every sample before it, the 100 that never
    reached the file too, is in summary.json's time, the TUM files and run.parquet."""
    import errno

    from sim.run import samples

    written, write = [], os.pwrite

    def pwrite(descriptor: int, data, offset: int) -> int:
        if len(written) >= 2 * 6:  # (two windows of the run's 6 columns)
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        written.append(offset)
        return write(descriptor, data, offset)

    monkeypatch.setattr(samples, "WINDOW", 100)
    monkeypatch.setattr(samples.os, "pwrite", pwrite)
    out = tmp_path / "out"
    assert main(["run", "empty", "--controller", "wander", "--duration", "5", "--no-report", "--seed", "4", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert "ctsim: run stopped: the run's samples from sample 200 on could not be written to the temporary folder" in err and "No space left on device" in err
    monkeypatch.undo()
    summary = json.loads((out / "summary.json").read_text())
    assert summary["reason"] == "error" and summary["time"] == pytest.approx(2.99)  # (samples 0-299: the third window whole)
    whole = tmp_path / "whole"
    assert main(["run", "empty", "--controller", "wander", "--duration", "2.99", "--no-report", "--seed", "4", "--out", str(whole)]) == 0
    for name in ("truth.tum", "fused.tum", "mouse.csv"):
        assert (out / name).read_bytes() == (whole / name).read_bytes()
    assert pq.read_table(out / "run.parquet").to_pandas().equals(pq.read_table(whole / "run.parquet").to_pandas())  # (NaN as NaN: IR seeing nothing)
