"""Sweeps: 200 runs give the same table on local processes and on a Dask LocalCluster; a sweep
killed half-way finishes on restart with every row once; a worker that dies costs only its run;
a run that raises is a row with its error; spec mistakes stop the CLI before anything runs."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
import warnings
from pathlib import Path

import pandas as pd
import pytest

from sim.analysis.nees import interval
from sim.cli.entry import main
from sim.experiments import Dask, Processes, Serial, load_results, sweep
from sim.experiments.engines import _dask_batch_size
from sim.experiments.store import PARTS

SPEC = """
[base]
duration = 0.2
[axes]
world = ["maze", "square", "empty", "line", "holes_lights"]
controller = ["solve_maze", "wander"]
"robot.encoders.slip_std" = [0.0, 0.01, 0.02, 0.05]
seed = [0, 1, 2, 3, 4]
"""
RUNS = 200  # 5 worlds x 2 controllers x 4 noise levels x 5 seeds

CRASH = """
import os
import signal
from pathlib import Path
from bots.commands import Twist

MARKER = Path(__file__).with_suffix(".died")

class Crash:
    '''Kills its process the first time it runs (always, with always=true); then drives on.'''
    def __init__(self, always: bool = False):
        self.always = always

    def step(self, t, readings):
        if self.always or not MARKER.exists():
            MARKER.touch()
            os.kill(os.getpid(), signal.SIGKILL)  # (a real death: os._exit in a run is the controller's error)
        return Twist(0.1, 0.0)

class Raise:
    def step(self, t, readings):
        raise ValueError("no good")

class Interrupt:
    '''Ctrl-C to its own process at step `at` (0: never).'''
    def __init__(self, at: int = 0):
        self.at, self.steps = at, 0

    def step(self, t, readings):
        self.steps += 1
        if self.steps == self.at:
            os.kill(os.getpid(), signal.SIGINT)
        return Twist(0.1, 0.0)
"""


def measured(table: pd.DataFrame) -> pd.DataFrame:
    """The table without the wall time, the one column that depends on the machine."""
    return table.drop(columns="wall_time_s")


@pytest.fixture(scope="module")
def spec_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("spec") / "noise.toml"
    path.write_text(SPEC)
    return path


@pytest.fixture(scope="module")
def reference(spec_file, tmp_path_factory) -> pd.DataFrame:
    """The 200-run sweep on local processes (2 workers)."""
    return sweep(spec_file, tmp_path_factory.mktemp("processes"), Processes(2), progress=False)


@pytest.fixture(scope="module")
def serial(spec_file, tmp_path_factory) -> pd.DataFrame:
    """The same 200 runs one after another in this process."""
    return sweep(spec_file, tmp_path_factory.mktemp("serial"), Serial(), progress=False)


def test_200_runs_on_processes(reference, serial):
    assert len(reference) == RUNS and reference["run_id"].is_unique
    assert (reference["reason"] == "duration").all(), reference.loc[reference.reason != "duration", "error"].tolist()
    assert list(reference["run"]) == list(range(RUNS))
    assert {"mouse.ate_rmse", "encoders.final_position_error", "robot.encoders.slip_std"} <= set(reference.columns)
    pd.testing.assert_frame_equal(measured(reference), measured(serial))


def test_dask_local_cluster_of_three_workers_gives_the_serial_table(spec_file, serial, tmp_path):
    """Three worker processes (tasks of several runs each) give the serial table bit for bit."""
    runner = Dask(workers=3)
    try:
        assert runner.workers == 3 and len({pid for pid in runner.client.run(os.getpid).values()}) == 3
        table = sweep(spec_file, tmp_path, runner, progress=False)
    finally:
        runner.close()
    pd.testing.assert_frame_equal(measured(table), measured(serial))


def test_dask_tasks_hold_a_few_runs_each_as_a_task_costs_more_than_a_message():
    """A Dask task costs some 8 ms of CPU beyond its runs (a local worker's message a fraction of
    one): the quick bench's 40 runs on two workers go two a task, a few runs one a task (every
    worker busy), larger sweeps in larger batches up to 8."""
    assert _dask_batch_size(40, 2) == 2 and _dask_batch_size(200, 2) == 4
    assert _dask_batch_size(4, 2) == _dask_batch_size(1, 8) == 1
    sizes = [_dask_batch_size(jobs, 2) for jobs in range(1, 5000)]
    assert sizes == sorted(sizes) and sizes[-1] == 8


def test_a_local_cluster_warns_nothing_where_port_8787_is_taken():
    """Another program on Dask's dashboard port (a notebook's cluster, a second sweep): the sweep's
    LocalCluster warned on stderr; its scheduler's few HTTP routes now take a free loopback port."""
    holder = socket.socket()
    try:
        with contextlib.suppress(OSError):  # (taken already: as good)
            holder.bind(("127.0.0.1", 8787))
            holder.listen()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            Dask(workers=1).close()
    finally:
        holder.close()
    assert not [w for w in caught if "already in use" in str(w.message)]


def test_killed_half_way_resumes_with_every_row_once(spec_file, reference, tmp_path):
    process = subprocess.Popen(
        [sys.executable, "-m", "sim.cli", "sweep", str(spec_file), "--out", str(tmp_path), "--jobs", "2"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    )
    try:
        _wait_for_parts(process, tmp_path, RUNS // 2)
    finally:
        os.killpg(process.pid, signal.SIGKILL)  # the parent and its workers, mid-run
        process.wait()
    kept = load_results(tmp_path)
    assert RUNS // 2 <= len(kept) < RUNS and kept["run_id"].is_unique
    ran = []
    table = sweep(spec_file, tmp_path, Processes(2), on_row=ran.append, progress=False)
    assert len(ran) == RUNS - len(kept)  # only the missing runs executed
    pd.testing.assert_frame_equal(measured(table), measured(reference))
    assert not list((tmp_path / PARTS).glob("*.parquet"))  # folded into results.parquet


def _wait_for_parts(process: subprocess.Popen, folder: Path, count: int) -> None:
    """Until `count` rows are on disk: decided by the rows, not the clock (pytest-timeout stops a
    sweep that never gets there)."""
    while len(list((folder / PARTS).glob("*.parquet"))) < count:
        assert process.poll() is None, "the sweep ended before it was stopped"
        time.sleep(0.05)


def _group_gone(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return True
    return False


@pytest.mark.parametrize("engine", ["processes", "dask"])
@pytest.mark.parametrize("signum, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["sigint", "sigterm"])
def test_a_signal_to_the_whole_group_stops_the_sweep_and_resume_finishes_it(spec_file, reference, tmp_path, signum, status, engine):
    """As a terminal's Ctrl-C (SIGINT to every process of the foreground group) or a job
    scheduler's SIGTERM: every process ends (a LocalCluster's workers too), with one line and no
    traceback; finished rows stay, the rest run on resume."""
    process = subprocess.Popen(
        [sys.executable, "-m", "sim.cli", "sweep", str(spec_file), "--out", str(tmp_path), "--jobs", "2", "--engine", engine],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )
    try:
        _wait_for_parts(process, tmp_path, 20)
        os.killpg(process.pid, signum)
        _, err = process.communicate()  # how soon is timed in bench/run.py (sweep_stop_after_sigint), not here
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    assert process.returncode == status and err.strip().splitlines()[-1] in ("ctsim: interrupted", "ctsim: terminated")
    assert "Traceback" not in err, err
    while not _group_gone(process.pid):  # the workers end with the sweep (else pytest-timeout says so)
        time.sleep(0.05)
    kept = load_results(tmp_path)
    assert 20 <= len(kept) < RUNS and kept["run_id"].is_unique
    assert (kept["reason"] == "duration").all()  # no run cut short by the signal became a row
    ran = []
    table = sweep(spec_file, tmp_path, Processes(2), on_row=ran.append, progress=False)
    assert len(ran) == RUNS - len(kept)
    pd.testing.assert_frame_equal(measured(table), measured(reference))


@pytest.mark.parametrize("make_runner", [lambda: Processes(2), lambda: Dask(workers=2)], ids=["processes", "dask"])
def test_a_signal_whose_exception_code_in_between_dropped_still_stops_the_engine(make_runner):
    """A handler's exception is raised wherever the main thread is; code that clears every error
    (pyarrow probing a pandas column's attributes while a sweep writes its row; a finalizer the
    garbage collector runs) dropped it, and the sweep ran to its end (exit 0 after SIGTERM). Here
    the caller's code drops it on purpose: the engine still stops when asked for the next outcome,
    and puts the handler back."""
    runner = make_runner()
    got = []
    try:
        with pytest.raises(KeyboardInterrupt):
            for _, outcome in runner.imap(abs, range(-40, 0)):
                got.append(outcome)
                if len(got) == 3:
                    try:
                        signal.raise_signal(signal.SIGINT)  # (its handler runs before this returns)
                    except KeyboardInterrupt:  # as such code does
                        pass
    finally:
        runner.close()
    assert len(got) == 3
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_ctrl_c_in_a_serial_sweep_records_no_cut_run(crash, tmp_path):
    """In-process runs see Ctrl-C themselves (the run loop ends the run early): that run is no
    row, and the sweep stops with the runs before it kept."""
    spec = {"base": {"duration": 0.3, "world": "empty", "controller": f"{crash}:Interrupt"}, "axes": {"params.at": [0, 5], "seed": [0, 1, 2]}}
    with pytest.raises(KeyboardInterrupt):
        sweep(spec, tmp_path / "out", Serial(), progress=False)
    kept = load_results(tmp_path / "out")
    assert list(kept["params.at"]) == [0, 0, 0] and (kept["reason"] == "duration").all()


@pytest.fixture()
def crash(tmp_path) -> Path:
    path = tmp_path / "crash.py"
    path.write_text(CRASH)
    return path


def _spec(controllers: list[str]) -> dict:
    return {"base": {"duration": 0.3, "world": "empty"}, "axes": {"controller": controllers, "seed": [0, 1]}}


@pytest.mark.parametrize("make_runner", [lambda: Processes(2), lambda: Dask(workers=2)], ids=["processes", "dask"])
def test_a_dying_worker_costs_only_its_run(crash, tmp_path, make_runner):
    runner = make_runner()
    try:
        table = sweep(_spec([f"{crash}:Crash", "wander"]), tmp_path / "out", runner, progress=False)
    finally:
        runner.close()
    assert crash.with_suffix(".died").exists()  # a worker did die
    assert len(table) == 4 and (table["reason"] == "duration").all()  # its run was retried


def test_a_run_that_always_kills_its_worker_is_recorded_lost(crash, tmp_path):
    spec = {"base": {"duration": 0.3, "world": "empty", "controller": f"{crash}:Crash", "params.always": True}, "axes": {"seed": [0]}}
    table = sweep(spec, tmp_path / "out", Processes(2, retries=1), progress=False)
    assert len(table) == 1 and (table["reason"] == "error").all()
    assert table["error"].str.contains("worker process died 2 times").all()


def test_a_run_that_raises_is_a_row_with_its_error(crash, tmp_path):
    table = sweep(_spec([f"{crash}:Raise", "wander"]), tmp_path / "out", Serial(), progress=False)
    failed = table[table["controller"].str.endswith("Raise")]
    assert len(table) == 4 and len(failed) == 2
    assert (failed["reason"] == "error").all() and failed["error"].str.contains("ValueError: no good").all()
    assert (table.loc[table.controller == "wander", "reason"] == "duration").all()


def test_artefacts_only_when_asked(tmp_path):
    spec = {"sweep": {"artefacts": ["tum", "recording"]}, "base": {"duration": 0.2, "world": "empty"}, "axes": {"seed": [0]}}
    table = sweep(spec, tmp_path / "with", Serial(), progress=False)
    folder = tmp_path / "with" / "runs" / table["run_id"][0]
    assert {p.name for p in folder.iterdir()} >= {"run.rrd", "truth.tum", "mouse.tum"}
    sweep({**spec, "sweep": {}}, tmp_path / "without", Serial(), progress=False)
    assert not (tmp_path / "without" / "runs").exists()


def test_cli_sweep_and_report(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text('[base]\nduration = 0.3\nworld = "empty"\n[axes]\nseed = [0, 1]\n"robot.mouse.noise_std" = [0.0, 0.002]\ncontroller = ["wander", "idle"]\n')
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--engine", "serial"]) == 0
    out = capsys.readouterr().out
    assert "8 runs, 0 failed" in out and "pooled over seed (2 values)" in out
    assert main(["sweep", "report", str(tmp_path / "out")]) == 0
    names = {Path(line).name for line in capsys.readouterr().out.splitlines() if line.startswith(str(tmp_path))}
    assert names == {"summary.csv", "ate_rmse_per_estimator.png", "ate_rmse_vs_robot.mouse.noise_std.png", "outcomes.png", "report.html"}
    page = (tmp_path / "out" / "report.html").read_text()
    assert page.count("src='data:image/png;base64,") == 3 and "<td>runs</td><td class='text'>8</td>" in page  # the figures inside; 8 runs


def _pixels_of(png: Path, rgb: tuple[int, int, int]) -> int:
    import matplotlib.image

    image = (matplotlib.image.imread(png)[..., :3] * 255).round().astype(int)
    return int((image == rgb).all(axis=-1).sum())


def test_the_sweep_figures_draw_each_estimator_in_its_colour(tmp_path):
    """Each estimator's box is drawn in its colour of the run figures and the viewer, filled with the
    pale form of it (areas of those exact colours), the outcome bars of runs that ran out of time in that outcome's colour."""
    from sim.experiments.report import write_report
    from sim.views import palette

    sweep({"base": {"duration": 2.0, "world": "empty", "controller": "wander"}, "axes": {"seed": [0, 1, 2], "robot.encoders.slip_std": [0.0, 0.05]}},
          tmp_path / "out", Serial(), progress=False)  # noise, so that the boxes have a height
    box, bars = (tmp_path / "out" / "figures" / name for name in ("ate_rmse_per_estimator.png", "outcomes.png"))
    write_report(tmp_path / "out")
    for name in ("encoders", "firmware"):  # boxes tall enough to have an inside
        assert _pixels_of(box, palette.pale(palette.estimate_colour(name))) > 100, name
    for name in ("encoders", "firmware", "mouse", "fused"):  # every box's edge and median
        assert _pixels_of(box, palette.estimate_colour(name)) > 20, name
    assert _pixels_of(bars, palette.OUTCOMES["time limit"]) > 1000


def test_report_groups_by_the_named_settings_and_says_what_it_pools(tmp_path, capsys):
    """Per controller: the noise levels and seeds pooled (2 x 2 runs a group); the table's means
    are those of the runs it groups; a setting the sweep lacks is one line naming it."""
    spec = {"base": {"duration": 0.3, "world": "empty"}, "axes": {"seed": [0, 1], "robot.mouse.noise_std": [0.0, 0.002], "controller": ["wander", "idle"]}}
    table = sweep(spec, tmp_path / "out", Serial(), progress=False)
    assert main(["sweep", "report", str(tmp_path / "out"), "--by", "controller"]) == 0
    out = capsys.readouterr().out
    assert "per controller; pooled over seed (2 values), robot.mouse.noise_std (2 values):" in out
    summary = pd.read_csv(tmp_path / "out" / "summary.csv")
    assert list(summary["controller"]) == ["idle", "wander"] and (summary["runs"] == 4).all()
    wander = table[table.controller == "wander"]["mouse.ate_rmse"]
    assert summary.loc[1, "mouse.ate_rmse.mean"] == pytest.approx(wander.mean(), rel=1e-12)  # (CSV round trip of a float)
    assert summary.loc[1, "mouse.ate_rmse.std"] == pytest.approx(wander.std(), rel=1e-12)
    ends = table[table.controller == "wander"]["mouse.nees_final"]  # NEES over the runs, against the interval of that many
    assert summary.loc[1, "mouse.nees.mean"] == pytest.approx(ends.mean(), rel=1e-12) and summary.loc[1, "mouse.nees.runs"] == 4
    assert (summary.loc[1, "mouse.nees.low"], summary.loc[1, "mouse.nees.high"]) == pytest.approx(interval(4), rel=1e-12)
    assert summary.loc[1, "mouse.nees.verdict"] in ("consistent", "over-confident", "too cautious")
    assert "NEES at the runs' end per estimator" in out and f"its 95 % interval {interval(4)[0]:.2f}–{interval(4)[1]:.2f} for that many runs" in out
    assert main(["sweep", "report", str(tmp_path / "out"), "--by", "robot.wheels"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ctsim: error: no setting 'robot.wheels' in this sweep") and err.count("\n") == 1


@pytest.mark.parametrize(
    "text, message",
    [
        ('[axes]\nworld = ["maze", "nowhere"]\n', "run 1, world 'nowhere'"),
        ('[axes]\ncontroller = ["solve_maze", "solve_mase"]\n', "did you mean 'solve_maze'"),
        ('[axes]\n"robot.encoders.slipp" = [0.1]\n', "no field 'slipp'"),
        ('[base]\nduration = -1\n', "[base]: duration: must be a number (s) at least 0"),
        ("[axes\n", "s.toml"),
    ],
)
def test_cli_spec_mistakes_exit_2_before_anything_runs(tmp_path, capsys, text, message):
    spec = tmp_path / "s.toml"
    spec.write_text(text)
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ctsim: error:") and message in err and err.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_a_local_cluster_left_without_workers_is_given_up_after_a_while(monkeypatch):
    """Every worker dead and none started again (a nanny under a heavy load): the runs left are
    lost after WORKERLESS_S, looked at every WORKERS_EVERY_S; a cluster of someone else's is waited for."""
    from types import SimpleNamespace

    from sim.experiments import engines

    now = [0.0]
    monkeypatch.setattr(engines, "time", SimpleNamespace(monotonic=lambda: now[0]))
    workers: dict = {}
    own = SimpleNamespace(cluster=object(), client=SimpleNamespace(scheduler_info=lambda n_workers: {"workers": workers}))
    watch, theirs = engines._Workerless(own), engines._Workerless(SimpleNamespace(cluster=None, client=None))
    given_up = []
    for second in range(100):
        now[0] = float(second)
        given_up.append(watch.too_long())
        assert not theirs.too_long()
    first = engines.WORKERS_EVERY_S + engines.WORKERLESS_S  # (none seen at the first look, 5 s in; 60 s later: given up)
    assert given_up.index(True) == first
    workers["tcp://w"] = {}
    now[0] += engines.WORKERS_EVERY_S
    assert not watch.too_long() and watch.since is None
