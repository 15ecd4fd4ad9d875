"""`ctsim evaluate`: estimators scored on the fixed suite beside the shipped ones, ranked, into a
results file that is the same bytes for the same suite and seeds and merges only with its own
suite version and scenario hashes; a mistake (a missing file, an estimator that raises, another
version's results) is one line and exit status 2.

The suite's `test` variant (2 short scenarios x 2 seeds) stands for `short` here: the same code,
in seconds rather than a minute."""

from __future__ import annotations

import json
import shutil
import textwrap
from dataclasses import replace
from pathlib import Path

import pytest

from sim.cli.entry import main
from sim.experiments.engines import Processes, Serial
from sim.experiments.evaluation import RESULTS, EvaluationError, evaluate, merge, read_results
from sim.experiments.scores import per_scenario, ranking
from sim.experiments.suite import VARIANTS

ROOT = Path(__file__).resolve().parents[1]
EULER = f"{ROOT / 'docs' / 'examples' / 'euler_odometry.py'}:EulerOdometry"
SUITE = VARIANTS["test"]


@pytest.fixture(scope="module")
def scored(tmp_path_factory) -> tuple[dict, Path]:
    """The test suite with the Euler example, one run after another in this process."""
    out = tmp_path_factory.mktemp("evaluate") / "serial"
    return evaluate(SUITE, [EULER], out, Serial(), progress=False), out


def test_the_euler_example_ranks_below_the_exact_arc(scored):
    results, _ = scored
    table = ranking(per_scenario(results))
    rank = dict(zip(table["estimator"], table["rank"]))
    assert rank["euler"] > rank["encoders"]
    assert set(rank) == {"encoders", "firmware", "mouse", "fused", "localiser", "euler"}
    assert (table["failed"] == 0).all()


def test_two_runs_of_the_suite_give_the_same_results_file_on_any_engine(scored, tmp_path):
    _, first = scored
    engine = Processes(2)
    try:
        evaluate(SUITE, [EULER], tmp_path / "again", engine, progress=False)
    finally:
        engine.close()
    assert (tmp_path / "again" / RESULTS).read_bytes() == (first / RESULTS).read_bytes()


def test_the_same_call_again_runs_nothing_and_writes_the_same_file(scored, tmp_path):
    _, first = scored
    folder = tmp_path / "resumed"
    shutil.copytree(first, folder)
    ran = []
    evaluate(SUITE, [EULER], folder, Serial(), progress=False, on_row=ran.append)
    assert ran == [] and (folder / RESULTS).read_bytes() == (first / RESULTS).read_bytes()


def test_the_results_file_names_the_suite_its_hashes_and_every_runs_metrics(scored):
    results, out = scored
    assert (results["suite"], results["seeds"]) == ("test", [0, 1])
    assert set(results["scenarios"]) == {s.name for s in SUITE.scenarios}
    assert all(len(s["hash"]) == 64 for s in results["scenarios"].values())
    assert results["estimators"]["euler"]["source"] == "euler_odometry.py:EulerOdometry"
    assert len(results["runs"]) == len(SUITE.scenarios) * len(SUITE.seeds)
    assert {tuple(sorted(run["metrics"])) for run in results["runs"]} == {("encoders", "euler", "firmware", "fused", "localiser", "mouse")}
    assert str(ROOT) not in (out / RESULTS).read_text()  # (nothing of the machine it ran on)


def test_a_scenario_hash_follows_the_world_file_and_the_noise_not_where_ctsim_lies(tmp_path, monkeypatch):
    scenario = SUITE.scenarios[0]
    shipped = scenario.digest()
    assert replace(scenario, noise="harsh").digest() != shipped
    text = scenario.world_path().read_bytes()
    monkeypatch.setattr("sim.world.files.worlds_dir", lambda: tmp_path)
    (tmp_path / scenario.world).write_bytes(text)
    assert scenario.digest() == shipped
    (tmp_path / scenario.world).write_bytes(text + b"\n# a comment\n")
    assert scenario.digest() != shipped


def _with_estimator(results: dict, name: str, identity: str, scale: float) -> dict:
    """A copy of `results` as another person's file: their estimator `name` beside the shipped ones."""
    other = json.loads(json.dumps(results))
    other["estimators"] = {name: {"source": f"{name}.py", "identity": identity}}
    for run in other["runs"]:
        run["metrics"][name] = {k: (None if v is None else v * scale) for k, v in run["metrics"].pop("euler").items()}
    return other


def test_merged_results_hold_every_estimator_and_refuse_another_suite(scored):
    results, _ = scored
    other = _with_estimator(results, "theirs", "sha256:other", 0.5)
    merged = merge([results, other])
    assert set(merged["estimators"]) == {"euler", "theirs"}
    table = ranking(per_scenario(merged))
    assert list(table["estimator"]).index("theirs") < list(table["estimator"]).index("euler")  # half the errors rank higher
    stale = {**other, "scenarios": {**other["scenarios"], "line_none_20s": {**other["scenarios"]["line_none_20s"], "hash": "0" * 64}}}
    with pytest.raises(EvaluationError, match="scenario hashes differ"):
        merge([results, stale])
    with pytest.raises(EvaluationError, match="another file"):
        merge([results, _with_estimator(results, "euler", "sha256:other", 1.0)])
    shipped_differs = json.loads(json.dumps(other))
    shipped_differs["runs"][0]["metrics"]["encoders"]["ate_rmse"] *= 2
    with pytest.raises(EvaluationError, match="scored differently"):
        merge([results, shipped_differs])


def test_merge_on_the_command_line_writes_the_joined_table(scored, tmp_path, capsys):
    results, out = scored
    theirs = tmp_path / "theirs.json"
    theirs.write_text(json.dumps(_with_estimator(results, "theirs", "sha256:other", 0.5)))
    assert main(["evaluate", "--merge", str(out / RESULTS), str(theirs), "--out", str(tmp_path / "merged")]) == 0
    printed = capsys.readouterr().out
    assert "theirs" in printed and "euler" in printed
    merged = read_results(tmp_path / "merged" / RESULTS)
    assert set(merged["estimators"]) == {"euler", "theirs"}
    assert list(per_scenario(merged)["scenario"].unique()) == [s.name for s in SUITE.scenarios]  # (the suite's order, not the file's sorted keys)
    assert {p.name for p in (tmp_path / "merged").iterdir()} >= {RESULTS, "scores.csv", "ranking.csv", "report.html"}


RAISES_IN_UPDATE = """
class Broken:
    def reset(self, robot, pose):
        self.pose = pose

    def update(self, readings):
        raise RuntimeError("no idea where I am")
"""
RAISES_IN_INIT = """
class Broken:
    def __init__(self):
        raise ValueError("not today")

    def reset(self, robot, pose): ...
    def update(self, readings): ...
"""


@pytest.mark.parametrize(("text", "expected"), [(None, "no such estimator file"), (RAISES_IN_UPDATE, "no idea where I am"), (RAISES_IN_INIT, "not today")])
def test_a_bad_estimator_is_one_line_and_exit_2_before_anything_runs(tmp_path, capsys, text, expected):
    path = tmp_path / "mine.py"
    if text is not None:
        path.write_text(textwrap.dedent(text))
    out = tmp_path / "out"
    assert main(["evaluate", f"{path}:Broken", "--suite", "test", "--out", str(out), "--engine", "serial"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ctsim: error:") and expected in err[0]
    assert not (out / RESULTS).exists()


def _broken_run(results: dict) -> dict:
    broken = json.loads(json.dumps(results))
    broken["runs"][1]["metrics"]["encoders"]["ate_rmse"] = "small"
    return broken


CHANGES = {"suite_version": lambda r: {**r, "suite_version": "0"}, "format": lambda r: {**r, "format": "0"}, "runs missing": lambda r: {**r, "runs": r["runs"][1:]},
           "a metric not a number": _broken_run, "a name not a word": lambda r: {**r, "estimators": {"\x1b[31mred": r["estimators"]["euler"]}}}  # fmt: skip


@pytest.mark.parametrize("change", [*CHANGES, "not json"])
def test_a_results_file_of_another_version_or_shape_is_one_line_and_exit_2(scored, tmp_path, capsys, change):
    results, out = scored
    other = tmp_path / "other.json"
    other.write_text("{" if change == "not json" else json.dumps(CHANGES[change](results)))
    assert main(["evaluate", "--merge", str(out / RESULTS), str(other), "--out", str(tmp_path / "merged")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ctsim: error:") and "other.json" in err[0]


def test_ctrl_c_keeps_the_finished_runs_and_the_same_call_runs_only_the_rest(scored, tmp_path):
    results, first = scored
    folder = tmp_path / "stopped"

    def stop(row: dict) -> None:
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        evaluate(SUITE, [EULER], folder, Serial(), progress=False, on_row=stop)
    ran = []
    evaluate(SUITE, [EULER], folder, Serial(), progress=False, on_row=ran.append)
    assert len(ran) == len(results["runs"]) - 1
    assert (folder / RESULTS).read_bytes() == (first / RESULTS).read_bytes()


FAILS_LATER = """
import numpy as np

class Later:
    def reset(self, robot, pose):
        self.pose, self.steps = np.array(pose, dtype=float), 0

    def update(self, readings):
        self.steps += 1
        if self.steps > 1000:
            raise RuntimeError("lost my mind after ten seconds")
"""


def test_an_estimator_that_fails_mid_run_is_a_failed_run_ranked_last_and_exit_1(tmp_path, capsys):
    path = tmp_path / "later.py"
    path.write_text(textwrap.dedent(FAILS_LATER))
    out = tmp_path / "out"
    assert main(["evaluate", EULER, str(path), "--suite", "test", "--out", str(out), "--engine", "serial"]) == 1
    results = read_results(out / RESULTS)
    failed = {run["scenario"]: run.get("failed", {}) for run in results["runs"]}  # (the 4 s maze runs end before step 1000, the 20 s line runs do not)
    assert not failed["maze_realistic_4s"] and "lost my mind" in failed["line_none_20s"]["Later"]
    assert "2 of 4 runs failed" in capsys.readouterr().err
    assert ranking(per_scenario(results))["estimator"].iloc[-1] == "Later"


HOSTILE = """
import os, sys, threading, time
import numpy as np

AT = {at}

class Base:
    def reset(self, robot, pose):
        self.pose, self.steps = np.array(pose, dtype=float), 0
        self.covariance = np.eye(3) * 1e-4

    def update(self, readings):
        self.steps += 1
        if self.steps > AT:
            self.fail()

class Sleeps(Base):
    def fail(self): time.sleep(1000)
class Loops(Base):
    def fail(self):
        while True:
            pass
class Raises(Base):
    def fail(self): raise RuntimeError("boom")
class Interrupts(Base):
    def fail(self): raise KeyboardInterrupt
class NanPose(Base):
    def fail(self): self.pose = np.array([np.nan, 0.0, 0.0])
class Asymmetric(Base):
    def fail(self): self.covariance = np.array([[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
class NegativeDefinite(Base):
    def fail(self): self.covariance = -np.eye(3)
class Exits(Base):
    def fail(self): sys.exit(3)
class OsExit(Base):
    def fail(self): os._exit(4)
class ThreadExits(Base):
    def fail(self):
        thread = threading.Thread(target=os._exit, args=(5,))
        thread.start()
        thread.join()
"""
HOSTILE_SAID = {
    "Sleeps": "took longer than the step time limit of 0.3 s", "Loops": "took longer than the step time limit of 0.3 s",
    "Raises": "raised RuntimeError: boom", "Interrupts": "raised KeyboardInterrupt", "NanPose": "its pose is not finite (nan)",
    "Asymmetric": "its covariance is not symmetric", "NegativeDefinite": "its covariance is not positive semi-definite",
    "Exits": "called sys.exit(3)", "OsExit": "called os._exit(4)", "ThreadExits": "called os._exit(5) from the thread",
}  # fmt: skip
"""What the line says of each hostile estimator (each also names itself and the step)."""


def _hostile(tmp_path: Path, at: int) -> Path:
    path = tmp_path / "hostile.py"
    path.write_text(textwrap.dedent(HOSTILE.format(at=at)))
    return path


@pytest.mark.parametrize("cls", HOSTILE_SAID)
def test_an_estimator_that_fails_its_trial_in_any_way_is_one_line_and_exit_2(cls, tmp_path, capsys):
    """Hangs under a short --step-timeout too: the trial runs each call of it under the limit."""
    out = tmp_path / "out"
    assert main(["evaluate", f"{_hostile(tmp_path, 1)}:{cls}", "--suite", "test", "--out", str(out), "--engine", "serial", "--step-timeout", "0.3"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ctsim: error: ") and f"estimator '{cls}' of ctbot" in err[0] and "at step 1 " in err[0]
    assert HOSTILE_SAID[cls] in err[0]
    assert not (out / RESULTS).exists()


@pytest.mark.parametrize("cls", ["Sleeps", "Interrupts", "NegativeDefinite"])
def test_an_estimator_that_fails_mid_suite_fails_only_its_runs_with_one_line_each(cls, tmp_path, capsys):
    """After step 500 (past the 4 s maze runs' 400 steps; within the 20 s line runs): the maze runs
    are kept and scored, each line run is a failed run said in one line naming the estimator's
    file, itself and the step (a hang meets --step-timeout), exit 1, every file written."""
    path = _hostile(tmp_path, 500)
    out = tmp_path / "out"
    assert main(["evaluate", f"{path}:{cls}", "--suite", "test", "--out", str(out), "--engine", "serial", "--step-timeout", "0.3"]) == 1
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if " seed " in line and " failed: " in line]
    assert [line.split(" failed: ")[0] for line in lines] == ["ctsim: line_none_20s seed 0", "ctsim: line_none_20s seed 1"]
    assert all(f"hostile.py:{cls}: estimator '{cls}' of ctbot" in line and "at step 500 " in line and HOSTILE_SAID[cls] in line for line in lines), lines
    assert "2 of 4 runs failed" in err
    results = read_results(out / RESULTS)
    runs = {(run["scenario"], run["seed"]): run for run in results["runs"]}
    assert all(not runs["maze_realistic_4s", seed].get("failed") and cls in runs["maze_realistic_4s", seed]["metrics"] for seed in (0, 1))
    assert all(HOSTILE_SAID[cls] in runs["line_none_20s", seed]["failed"][cls] for seed in (0, 1))
    assert {p.name for p in out.iterdir()} >= {RESULTS, "scores.csv", "ranking.csv", "report.html"}


def test_a_hang_meets_the_step_time_limit_on_worker_processes_too(tmp_path, capsys):
    """The default engine: each worker runs its runs in its main thread, where the step clock holds."""
    out = tmp_path / "out"
    assert main(["evaluate", f"{_hostile(tmp_path, 500)}:Sleeps", "--suite", "test", "--out", str(out), "--jobs", "2", "--step-timeout", "0.3"]) == 1
    failed = [run.get("failed", {}) for run in read_results(out / RESULTS)["runs"]]
    assert [bool(f) for f in failed] == [False, False, True, True] and all("step time limit of 0.3 s at step 500" in f["Sleeps"] for f in failed[2:])


@pytest.mark.parametrize("planted", [RESULTS, "report.html"])
def test_a_folder_planted_at_a_results_name_fails_the_writing_alone_naming_every_file_written(scored, tmp_path, capsys, planted):
    """The runs are kept (resumed here: all done); the other files are written; exit 1, and the
    line names exactly the files written (no traceback, not the options' exit 2)."""
    _, first = scored
    folder = tmp_path / "again"
    shutil.copytree(first, folder)
    for name in (RESULTS, "scores.csv", "ranking.csv", "report.html"):
        (folder / name).unlink(missing_ok=True)
    (folder / planted).mkdir()
    assert main(["evaluate", EULER, "--suite", "test", "--out", str(folder), "--engine", "serial"]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err and f"{folder / planted} is a folder" in err
    written = err.rsplit("(written: ", 1)[1].rstrip(")\n").split(", ")
    assert sorted(written) == sorted(p.name for p in folder.iterdir() if p.is_file() and p.name != "results.parquet" and not p.name.startswith("."))
    assert (folder / planted).is_dir() and len(written) == 3
