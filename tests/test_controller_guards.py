"""A controller that takes the run's guards with it (ignores signals, stops the step timer,
leaves a thread, calls os._exit from a thread, forks, closes stdout, replaces numpy or ctsim,
lowers the recursion limit) still ends the run with its data and the documented exit status
(`sim.guards`)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import numpy
import pytest

import sim.run.loop
from sim.cli.entry import main

pytestmark = pytest.mark.skipif(not hasattr(signal, "setitimer"), reason="the step timer and fork are POSIX")

CONTROLLERS = '''
import os, signal, sys, threading, time
import numpy
from bots.commands import Twist

class IgnoresThenBlocks:
    """Ignores Ctrl-C, SIGTERM and the step timer's signal, stops the timer and blocks its signal,
    then, after the guards' next full check (EVERY steps on), finds the timer running again at the
    run's interval and stands for a step that blocks: the timer's ticks it would wait for it raises
    itself, at once (they reach the clock only with its handler back and the signal unblocked)."""
    def step(self, t, readings):
        if t < 0.02:
            for number in (signal.SIGINT, signal.SIGTERM, signal.SIGALRM):
                signal.signal(number, signal.SIG_IGN)
            signal.setitimer(signal.ITIMER_REAL, 0)
            signal.pthread_sigmask(signal.SIG_BLOCK, [signal.SIGALRM])
        elif t > 0.4:  # (after the next full check: EVERY = 32 steps of 0.01 s)
            interval = signal.getitimer(signal.ITIMER_REAL)[1]
            if interval != 15.0:  # (a quarter of --step-timeout 60)
                raise RuntimeError(f"the step timer runs at {interval} s")
            for _ in range(8):
                signal.raise_signal(signal.SIGALRM)
            raise RuntimeError("the step timer's ticks did not reach the clock")  # (not reached: the fifth tick in this step ends it)
        return Twist(0.1, 0.0)

class LeavesAThread:
    def step(self, t, readings):
        if t > 0.05 and not hasattr(self, "thread"):
            self.thread = threading.Thread(target=time.sleep, args=(1000,))
            self.thread.start()
        return Twist(0.1, 0.0)

class ExitsFromAThread:
    def step(self, t, readings):
        if t > 0.05:
            thread = threading.Thread(target=os._exit, args=(0,))
            thread.start()
            thread.join()
        return Twist(0.1, 0.0)

class Forks:
    def step(self, t, readings):
        if t > 0.05 and not hasattr(self, "child"):
            self.child = os.fork()
        return Twist(0.1, 0.0)

class ClosesStdout:
    def step(self, t, readings):
        if t > 0.05 and not sys.stdout.closed:
            sys.stdout.close()
            os.close(1)
        return Twist(0.1, 0.0)

class Patches:
    def step(self, t, readings):
        if t > 0.05:
            numpy.zeros = None
            import sim.run.loop
            sim.run.loop._sample = None
        return Twist(0.1, 0.0)

class RearmsTheTimerFarAhead:
    """Keeps the step timer's interval, moves its next expiry a day ahead, then blocks the next
    step (before the guards' next full check: only the check after every step catches it)."""
    def step(self, t, readings):
        if 0.085 < t < 0.095:
            signal.setitimer(signal.ITIMER_REAL, 86400.0, signal.getitimer(signal.ITIMER_REAL)[1])
        elif t > 0.095:
            time.sleep(1000)
        return Twist(0.1, 0.0)

class ExitsThroughPosix:
    def step(self, t, readings):
        if t > 0.05 and not hasattr(self, "thread"):
            import posix
            self.thread = threading.Thread(target=posix._exit, args=(0,))
            self.thread.start()
            self.thread.join()
        return Twist(0.1, 0.0)

class RedirectsOutput:
    def step(self, t, readings):
        if t > 0.05:
            quiet = os.open(os.devnull, os.O_WRONLY)
            os.dup2(quiet, 1)
            os.dup2(quiet, 2)
            os.close(quiet)
        return Twist(0.1, 0.0)

class ReplacesJsonDumps:
    def step(self, t, readings):
        import json
        json.dumps = lambda *args, **kwargs: "{}"
        return Twist(0.1, 0.0)

class StatusThatBlocks:
    """A behaviour whose `status`, read by the run after each step, blocks for ever from its sixth step on
    (and from the start where `at_once`)."""
    at_once = False
    def __init__(self):
        self.steps = 0
    def step(self, t, readings):
        self.steps += 1
        return Twist(0.1, 0.0)
    @property
    def status(self):
        if self.at_once or self.steps > 5:
            time.sleep(10**6)
        from bots.controller import Status
        return Status.RUNNING

class StatusThatBlocksAtOnce(StatusThatBlocks):
    at_once = True

class LowersTheRecursionLimit:
    def step(self, t, readings):
        if t > 0.05:
            sys.setrecursionlimit(80)
        return Twist(0.1, 0.0)
'''


@pytest.fixture()
def controllers(tmp_path) -> Path:
    path = tmp_path / "hostile.py"
    path.write_text(CONTROLLERS)
    return path


def run(controllers: Path, name: str, out: Path) -> int:
    return main(["run", "empty", "--controller", f"{controllers}:{name}", "--duration", "0.2", "--step-timeout", "0.4", "--no-report", "--out", str(out)])


def summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


def test_a_controller_that_ignores_signals_and_stops_the_timer_still_meets_the_step_limit(controllers, tmp_path, capsys):
    """Decided by no clock. With --step-timeout 0.4 the blocking step waited for the timer, and on a
    machine under a load of about 20 the test failed now and then: a step's time limit is wall-clock
    time, which load stretches (any step that the timer's ticks found unfinished for 0.3 s ended the
    run, this controller's first steps too). The limit here is 60 s, which no step of it comes near,
    and the ticks of the blocking step are its own."""
    argv = ["run", "empty", "--controller", f"{controllers}:IgnoresThenBlocks", "--duration", "0.6", "--step-timeout", "60", "--no-report"]
    before = signal.getsignal(signal.SIGINT)  # (SIG_IGN where pytest was started in the background)
    assert main([*argv, "--out", str(tmp_path / "out")]) == 1
    assert "took longer than the step time limit of 60 s at step 41" in capsys.readouterr().err
    assert summary(tmp_path / "out")["time"] == pytest.approx(0.41)
    assert signal.getsignal(signal.SIGINT) == before  # and the process has its own back


@pytest.mark.parametrize(("name", "step"), [("StatusThatBlocks", 6), ("StatusThatBlocksAtOnce", 0)])
def test_a_status_that_blocks_ends_the_run_as_its_step_would(name, step, controllers, tmp_path, capsys):
    """The run reads a behaviour's `status` after every step (is it done?): user code, under the
    step's time limit as its step is; the run's end reads none again (the status last read)."""
    assert run(controllers, name, tmp_path / "out") == 1
    err = capsys.readouterr().err
    assert f"{name}' of ctbot took longer than the step time limit of 0.4 s in its status at step {step} (t = {step / 100:.2f} s)" in err
    assert summary(tmp_path / "out")["reason"] == "error"
    assert (tmp_path / "out" / "truth.tum").read_text().count("\n") == 1 + step + 1


def test_os_exit_from_a_thread_ends_the_run_with_its_data(controllers, tmp_path, capsys):
    assert run(controllers, "ExitsFromAThread", tmp_path / "out") == 1
    assert "called os._exit(0) from the thread" in capsys.readouterr().err
    assert summary(tmp_path / "out")["reason"] == "error"
    assert (tmp_path / "out" / "truth.tum").read_text().count("\n") == 1 + 7


def test_a_fork_that_returns_into_the_run_leaves_and_writes_nothing(controllers, tmp_path):
    assert run(controllers, "Forks", tmp_path / "out") == 0
    assert summary(tmp_path / "out")["time"] == pytest.approx(0.2)
    assert (tmp_path / "out" / "truth.tum").read_text().count("\n") == 1 + 21  # written once, whole


def test_replacing_numpy_or_ctsim_ends_the_run_as_the_controllers_error_and_is_undone(controllers, tmp_path, capsys):
    zeros, sample = numpy.zeros, sim.run.loop._sample
    assert run(controllers, "Patches", tmp_path / "out") == 1
    assert "replaced numpy.zeros, sim.run.loop._sample, and the run failed" in capsys.readouterr().err
    assert numpy.zeros is zeros and sim.run.loop._sample is sample
    assert summary(tmp_path / "out")["reason"] == "error"


def test_a_lowered_recursion_limit_is_put_back(controllers, tmp_path):
    limit = sys.getrecursionlimit()
    assert run(controllers, "LowersTheRecursionLimit", tmp_path / "out") == 0
    assert sys.getrecursionlimit() == limit


SCRIPT = shutil.which("ctsim") or str(Path(sys.executable).parent / "ctsim")


def console(controllers: Path, name: str, out: Path) -> subprocess.CompletedProcess:
    """`ctsim run` as its console script, in a process of its own."""
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])}
    return subprocess.run([SCRIPT, "run", "empty", "--controller", f"{controllers}:{name}", "--duration", "0.2", "--no-report", "--out", str(out)],
                          capture_output=True, text=True, timeout=600, env=env)


@pytest.mark.skipif(not Path(SCRIPT).exists(), reason="needs the ctsim console script")
def test_a_thread_left_running_does_not_keep_ctsim_from_exiting(controllers, tmp_path):
    done = console(controllers, "LeavesAThread", tmp_path / "out")
    assert done.returncode == 0, done.stderr
    assert summary(tmp_path / "out")["reason"] == "duration"


@pytest.mark.skipif(not Path(SCRIPT).exists(), reason="needs the ctsim console script")
def test_closing_stdout_costs_neither_the_table_nor_the_exit_status(controllers, tmp_path):
    done = console(controllers, "ClosesStdout", tmp_path / "out")
    assert done.returncode == 0, done.stderr
    assert "time limit reached" in done.stdout and "wrote:" in done.stdout
    assert summary(tmp_path / "out")["reason"] == "duration"


def test_a_timer_rearmed_far_ahead_still_meets_the_step_limit(controllers, tmp_path, capsys):
    assert run(controllers, "RearmsTheTimerFarAhead", tmp_path / "out") == 1
    assert "took longer than the step time limit of 0.4 s at step 10" in capsys.readouterr().err


def test_posix_exit_from_a_thread_ends_the_run_with_its_data(controllers, tmp_path, capsys):
    assert run(controllers, "ExitsThroughPosix", tmp_path / "out") == 1
    assert "called os._exit(0) from the thread" in capsys.readouterr().err
    assert summary(tmp_path / "out")["reason"] == "error"


def test_output_redirected_with_dup2_is_put_back(controllers, tmp_path, capfd):
    assert run(controllers, "RedirectsOutput", tmp_path / "out") == 0
    out, err = capfd.readouterr()
    assert "wrote:" in out and "redirected file descriptor 1 or 2; ctsim put it back" in err


def test_a_replaced_json_dumps_is_put_back_before_the_summary_is_written(controllers, tmp_path, capsys):
    dumps = json.dumps
    assert run(controllers, "ReplacesJsonDumps", tmp_path / "out") == 0
    assert json.dumps is dumps and summary(tmp_path / "out")["reason"] == "duration"
    assert "replaced json.dumps; ctsim put it back" in capsys.readouterr().err



def test_ctsims_own_frames_are_never_the_users_even_in_the_users_folder():
    """A controller kept in a folder that holds ctsim too (a clone with the student's files beside
    it): a failure inside ctsim stays ctsim's, not blamed on the controller."""
    from pathlib import Path

    from sim.guards import foreign_frame
    from sim.world.step import check_dt

    try:
        check_dt(-1.0)
    except Exception as err:  # noqa: BLE001 (whatever check_dt raises for a negative step)
        failure = err.with_traceback(err.__traceback__.tb_next)  # (ctsim's frames only, not this test's)
    root = str(Path(__file__).resolve().parents[1]) + "/"
    assert foreign_frame(failure, (root,)) is None


def test_an_estimator_that_forks_a_busy_loop_every_update_leaves_no_child_running(tmp_path):
    """A fork made during a run leaves in the child at once, before it returns into user code
    (`sim.guards._in_child`): an estimator whose children loop for ever (`ctsim evaluate` of one such
    ran for minutes, hundreds of children spinning, until killed) ends its run as usual, and every
    child it made has exited by itself."""
    from bots.commands import Twist
    from sim.experiments import Bot, simulate

    children: list[int] = []

    class ForksABusyLoop:
        def reset(self, robot, pose):
            self.pose = [float(v) for v in pose]

        def update(self, readings):
            child = os.fork()
            if child == 0:
                while True:
                    pass
            children.append(child)

    result = simulate("empty", Bot(lambda t, readings: Twist(0.1, 0.0)), duration=0.2, estimators=[ForksABusyLoop])
    assert result.error is None and len(children) == len(result.time)
    for child in children:  # (each has left with status 1; a child still looping would hang here until pytest's timeout)
        assert os.waitstatus_to_exitcode(os.waitpid(child, 0)[1]) == 1
