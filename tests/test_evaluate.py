"""`ctsim evaluate`: estimators scored on the fixed suite beside the shipped ones, ranked, into a
results file that is the same bytes for the same suite and seeds and merges only with its own
suite version and scenario hashes; a mistake (a missing file, an estimator that raises, another
version's results) is one line and exit status 2.

The suite's `test` variant (2 short scenarios x 2 seeds) stands for `short` here: the same code,
in seconds rather than a minute."""

from __future__ import annotations

import json
import math
import shutil
import textwrap
from dataclasses import replace
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from sim.cli.entry import main
from sim.experiments.engines import Processes, Serial
from sim.experiments.evaluation import RESULTS, EvaluationError, evaluate, merge, read_results
from sim.experiments.scores import _shown, per_scenario, ranking
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


def test_isolated_estimators_give_the_same_results_file(scored, tmp_path):
    """--isolate: readings go to the estimator's own process and poses come back as plain numbers
    (JSON keeps every bit of a double), so every metric is the same."""
    _, first = scored
    evaluate(SUITE, [EULER], tmp_path / "isolated", Serial(), progress=False, isolate=True)
    assert (tmp_path / "isolated" / RESULTS).read_bytes() == (first / RESULTS).read_bytes()


def test_an_isolated_estimators_code_never_runs_in_ctsims_processes(tmp_path):
    """An estimator that writes beside itself when it is made: in ctsim's process (and the trial's,
    and the engine's) it writes; isolated it cannot (the sandbox's files are read-only)."""
    from sim.sandbox import launch

    if launch.unavailable() is not None:
        pytest.skip(f"{launch.unavailable()}: without bubblewrap --isolate runs the code unisolated")
    code = tmp_path / "code" / "writes.py"
    code.parent.mkdir()
    code.write_text(textwrap.dedent("""
        from pathlib import Path

        class Writes:
            def reset(self, robot, pose):
                try:
                    Path(__file__).with_name("made").write_text("here")
                except OSError:  # (isolated: a read-only file system)
                    pass
                self.pose = [float(v) for v in pose]

            def update(self, readings):
                pass
    """))
    made = code.with_name("made")
    for isolate in (True, False):
        evaluate(SUITE, [str(code)], tmp_path / f"out{isolate}", Serial(), progress=False, isolate=isolate)
        assert made.exists() is not isolate


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


def _changed(results: dict, change) -> dict:  # noqa: ANN001 (a function changing a copy in place)
    copy = json.loads(json.dumps(results))
    change(copy)
    return copy


def _metric(results: dict, value: object, name: str = "ate_rmse") -> dict:
    return _changed(results, lambda r: r["runs"][1]["metrics"]["euler"].__setitem__(name, value))


def _ghost(r: dict) -> None:
    r["runs"][0]["metrics"]["ghost"] = r["runs"][0]["metrics"]["euler"]


def _million(r: dict) -> None:  # (a million runs: more than any suite has, refused by the suite's seeds)
    r["seeds"] = list(range(10**6))
    r["runs"] = [{"scenario": "maze_realistic_4s", "seed": seed, "metrics": {}} for seed in r["seeds"]]


CHANGES = {
    "suite_version": lambda r: {**r, "suite_version": "0"}, "format": lambda r: {**r, "format": "0"}, "runs missing": lambda r: {**r, "runs": r["runs"][1:]},
    "a metric not a number": lambda r: _metric(r, "small"), "a name not a word": lambda r: {**r, "estimators": {"\x1b[31mred": r["estimators"]["euler"]}},
    "a negative metric": lambda r: _metric(r, -1.0), "a metric true": lambda r: _metric(r, True), "a heading error beyond pi": lambda r: _metric(r, 4.0, "final_heading_error"),
    "format_version true": lambda r: {**r, "format_version": True}, "ctsim_version a list": lambda r: {**r, "ctsim_version": ["0.1"]},
    "ctsim_version with escapes": lambda r: {**r, "ctsim_version": "\x1b[2J\u202e0.1"}, "an unknown suite": lambda r: {**r, "suite": "mine"},
    "other seeds": lambda r: {**r, "seeds": [0, 2]}, "seeds as bools": lambda r: {**r, "seeds": [False, True]}, "a million runs": lambda r: _changed(r, _million),
    "an unknown key": lambda r: {**r, "note": "\ud800"}, "a scenario renamed": lambda r: _changed(r, lambda c: c["scenarios"].__setitem__("x", c["scenarios"].pop("line_none_20s"))),
    "a scenario's settings changed": lambda r: _changed(r, lambda c: c["scenarios"]["line_none_20s"].__setitem__("noise", "none ")),
    "two scenarios of one hash": lambda r: _changed(r, lambda c: [v.__setitem__("hash", "0" * 64) for v in c["scenarios"].values()]),
    "a hash not hex": lambda r: _changed(r, lambda c: c["scenarios"]["line_none_20s"].__setitem__("hash", "<b>")),
    "a run's seed a float": lambda r: _changed(r, lambda c: c["runs"][0].__setitem__("seed", 0.0)),
    "a run twice": lambda r: {**r, "runs": [r["runs"][0], *r["runs"]]}, "runs out of order": lambda r: {**r, "runs": r["runs"][::-1]},
    "metrics of an estimator not listed": lambda r: _changed(r, _ghost),
    "a failure of a shipped estimator": lambda r: _changed(r, lambda c: c["runs"][0].__setitem__("failed", {"encoders": "boom"})),
    "a failure with escapes": lambda r: _changed(r, lambda c: c["runs"][0].__setitem__("failed", {"euler": "\x1b[2Jboom"})),
    "a source with escapes": lambda r: _changed(r, lambda c: c["estimators"]["euler"].__setitem__("source", "\x1b[31m<script>.py")),
}  # fmt: skip
"""Results files edited by hand or by another program, each refused in one line naming the file."""
TEXTS = {
    "not json": lambda text: "{", "empty": lambda text: "", "NaN": lambda text: text.replace('"ate_rmse": 0.', '"ate_rmse": NaN, "x": 0.', 1),
    "Infinity": lambda text: text.replace('"ate_rmse": 0.', '"ate_rmse": Infinity, "x": 0.', 1),
    "a key twice": lambda text: text.replace('"format": ', '"format": "x", "format": ', 1), "nested 100,000 deep": lambda text: "[" * 100_000 + "]" * 100_000,
    "an integer of 5,000 digits": lambda text: text.replace('"seeds": [', '"seeds": [' + "9" * 5000 + ", ", 1),
    "not UTF-8": lambda text: text.replace("euler", "eul\udcffr", 1),
}  # fmt: skip
"""Results files that are not JSON as a results file holds it."""


@pytest.mark.parametrize("change", [*CHANGES, *TEXTS])
def test_a_results_file_of_another_version_or_shape_is_one_line_and_exit_2(scored, tmp_path, capsys, change):
    results, out = scored
    other = tmp_path / "other.json"
    if change in TEXTS:
        other.write_bytes(TEXTS[change]((out / RESULTS).read_text()).encode("utf-8", "surrogateescape"))
    else:
        other.write_text(json.dumps(CHANGES[change](results)))
    assert main(["evaluate", "--merge", str(out / RESULTS), str(other), "--out", str(tmp_path / "merged")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ctsim: error:") and "other.json" in err[0] and len(err[0]) < 400, err
    assert not (tmp_path / "merged").exists()


def _plant(path: Path, kind: str) -> None:
    """Something that is not a results file at `path`."""
    import os

    if kind == "pipe":
        os.mkfifo(path)
    elif kind == "folder":
        path.mkdir()
    elif kind == "link to a device":
        path.symlink_to("/dev/zero")
    elif kind == "dangling link":
        path.symlink_to(path.with_name("nowhere.json"))
    else:  # (sparse: it takes no room)
        with path.open("wb") as file:
            file.truncate(10**9)


@pytest.mark.skipif(not hasattr(__import__("os"), "mkfifo"), reason="named pipes are POSIX")
@pytest.mark.parametrize("kind", ["pipe", "folder", "link to a device", "dangling link", "a sparse file of 1 GB"])
def test_a_results_file_that_is_no_regular_file_or_too_large_is_refused_without_reading_it(scored, tmp_path, capsys, kind):
    """Not waited on (a pipe), not read into memory (/dev/zero, 1 GB): one line naming it, exit 2."""
    _, out = scored
    other = tmp_path / "other.json"
    _plant(other, kind)
    assert main(["evaluate", "--merge", str(out / RESULTS), str(other), "--out", str(tmp_path / "merged")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"ctsim: error: {other}: "), err


def test_a_link_to_a_results_file_is_read_as_the_file(scored, tmp_path):
    results, out = scored
    (tmp_path / "link.json").symlink_to(out / RESULTS)
    assert main(["evaluate", "--merge", str(out / RESULTS), str(tmp_path / "link.json"), "--out", str(tmp_path / "merged")]) == 0
    assert read_results(tmp_path / "merged" / RESULTS) == results


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
    assert str(tmp_path) not in (out / RESULTS).read_text()  # (the file's line by its name: nothing of the machine)
    page = (out / "report.html").read_text()
    assert "Failed runs (2 of 4)" in page and page.count(f"estimator &#x27;{cls}&#x27; of ctbot") == 2


def test_an_estimator_that_fails_a_run_leaves_the_others_metrics_as_in_a_run_without_it(scored, tmp_path, capsys):
    """The line runs, which `Raises` fails at step 500, run again without it: every other
    estimator's metrics of every run are those of the suite scored without it (`scored`: the world
    draws by robot and sensor, never by the set of estimators), and its failure is said as before."""
    without, _ = scored
    out = tmp_path / "out"
    assert main(["evaluate", EULER, f"{_hostile(tmp_path, 500)}:Raises", "--suite", "test", "--out", str(out), "--engine", "serial"]) == 1
    assert "2 of 4 runs failed" in capsys.readouterr().err
    results = read_results(out / RESULTS)
    for run, alone in zip(results["runs"], without["runs"]):
        assert {k: v for k, v in run["metrics"].items() if k != "Raises"} == alone["metrics"]  # (euler and the shipped ones, bit for bit)
        assert set(run.get("failed", {})) == ({"Raises"} if run["scenario"] == "line_none_20s" else set())
    assert all(HOSTILE_SAID["Raises"] in run["failed"]["Raises"] and "at step 500 " in run["failed"]["Raises"] for run in results["runs"][2:])
    table = ranking(per_scenario(results)).set_index("estimator")
    assert table.loc["euler", "failed"] == 0 and table.loc["Raises", "failed"] == 2 and table["rank"].idxmax() == "Raises"


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


HANGS_WHEN = """
import time

if {at!r} == "import":
    time.sleep(1000)


class Slow:
    def __init__(self):
        if {at!r} == "init":
            time.sleep(1000)

    def reset(self, robot, pose):
        self.pose = pose

    def update(self, readings):
        pass
"""


@pytest.mark.parametrize(("at", "line"), [("import", 5), ("init", 11)])
def test_an_estimator_file_that_hangs_while_it_is_loaded_or_made_is_one_line_and_exit_1(tmp_path, capsys, at, line):
    """Under twelve step time limits (a minute by default: a file may import a large library), as in `ctsim run`."""
    path = tmp_path / "slow.py"
    path.write_text(textwrap.dedent(HANGS_WHEN.format(at=at)))
    assert main(["evaluate", str(path), "--suite", "test", "--out", str(tmp_path / "out"), "--engine", "serial", "--step-timeout", "0.1"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"ctsim: error: loading or making the controllers and estimators took longer than 1.2 s (12 step time limits) ({path}:{line})"]


def _source(tmp_path: Path, kind: str) -> str:
    """An estimator argument of `ctsim evaluate` of the given hostile kind."""
    import os

    path = tmp_path / "mine.py"
    good = "class Mine:\n    def reset(self, robot, pose):\n        self.pose = pose\n\n    def update(self, readings):\n        pass\n"
    if kind == "a class it does not define":
        path.write_text(good)
        return f"{path}:Missing"
    if kind == "a syntax error":
        path.write_text("def broken(:\n")
    elif kind == "null bytes":
        path.write_bytes(b"class A:\x00\n")
    elif kind == "no estimator class":
        path.write_text("class Controller:\n    def step(self, t, readings):\n        pass\n")
    elif kind == "a class that is no estimator":
        path.write_text("class Controller:\n    def step(self, t, readings):\n        pass\n")
        return f"{path}:Controller"
    elif kind == "a number named as its class":
        path.write_text("X = 5\n")
        return f"{path}:X"
    elif kind == "a folder":
        path.mkdir()
    elif kind == "a pipe":
        os.mkfifo(path)
    elif kind == "a device":
        return "/dev/zero"
    elif kind == "a sparse file of 100 MB":
        path.write_text(good)
        with path.open("ab") as file:
            file.truncate(100 * 2**20)
    elif kind == "a name taken":
        path.write_text(good.replace("class Mine:", "class Mine:\n    name = 'encoders'"))
    return str(path)


@pytest.mark.skipif(not hasattr(__import__("os"), "mkfifo"), reason="named pipes are POSIX")
@pytest.mark.parametrize(("kind", "said"), [
    ("missing", "no such estimator file"), ("a class it does not define", "defines no 'Missing'"), ("a syntax error", "mine.py:1: SyntaxError"),
    ("null bytes", "cannot contain null bytes"), ("no estimator class", "expected one class with reset(robot, pose) and update(readings)"),
    ("a class that is no estimator", "'Controller' is not an estimator"), ("a number named as its class", "could not be made"),
    ("a folder", "not a regular file"), ("a pipe", "not a regular file"), ("a device", "/dev/zero: not a regular file"),
    ("a sparse file of 100 MB", "104,857,600 bytes, more than an estimator's file may have"), ("a name taken", "estimator name 'encoders' is taken"),
])  # fmt: skip
def test_an_estimator_argument_that_is_no_estimator_is_one_line_and_exit_2(tmp_path, capsys, kind, said):
    out = tmp_path / "out"
    assert main(["evaluate", _source(tmp_path, kind), "--suite", "test", "--out", str(out), "--engine", "serial"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ctsim: error:") and said in err[0], err
    assert not out.exists()


def test_a_hang_on_dask_ends_its_worker_and_the_run_is_lost_the_others_kept(tmp_path, capsys):
    """Dask runs its tasks in a worker's thread, where no signal reaches: an overrun ends the
    worker (`StepClock.ends_process`); Dask tries the run on fresh workers, then it is lost.
    The maze runs (400 steps) finish before the estimator's hang (step 500) and are kept. (Under a
    heavy load a nanny may fail to start a worker after some deaths: the runs left are lost after
    WORKERLESS_S, not waited for.)"""
    out = tmp_path / "out"
    assert main(["evaluate", f"{_hostile(tmp_path, 500)}:Sleeps", "--suite", "test", "--out", str(out), "--engine", "dask", "--jobs", "2", "--step-timeout", "0.3"]) == 1
    failed = [run.get("failed", {}) for run in read_results(out / RESULTS)["runs"]]
    assert [bool(f) for f in failed] == [False, False, True, True] and all(f["Sleeps"].startswith("run lost: ") for f in failed[2:])
    assert "ctsim: line_none_20s seed 0 failed: hostile.py:Sleeps: run lost" in capsys.readouterr().err


WANDERS = """
import os

os.chdir({away!r})


class Wanders:
    def reset(self, robot, pose):
        os.chdir({away!r})
        self.pose = pose

    def update(self, readings):
        pass
"""


def test_an_estimator_that_changes_the_current_folder_moves_no_result(tmp_path, monkeypatch):
    """At its import and in its reset (the trial runs in this process): a relative --out and
    estimator file are taken from the folder ctsim started in."""
    from sim.cli import output

    away = tmp_path / "away"
    away.mkdir()
    (tmp_path / "wanders.py").write_text(textwrap.dedent(WANDERS.format(away=str(away))))
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(output, "START", tmp_path)
    assert main(["evaluate", "wanders.py", "--suite", "test", "--out", "results", "--engine", "serial"]) == 0
    assert (tmp_path / "results" / RESULTS).is_file() and not any(away.iterdir())


def test_more_jobs_than_four_per_core_are_refused_before_any_starts(tmp_path, capsys):
    """A Dask LocalCluster started as many worker processes as asked (a million)."""
    assert main(["evaluate", "--suite", "test", "--engine", "dask", "--jobs", "1000000", "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("ctsim: error: --jobs 1000000: more worker processes than 4 per core")


def test_ctrl_c_during_the_trial_is_an_interrupt_not_a_refused_estimator(tmp_path, capsys, ctrl_c):
    """The trial is a run of its own: Ctrl-C there stops the command (130), not 'estimator ...: interrupted' (2)."""
    path = tmp_path / "ctrl_c.py"
    path.write_text("import signal\n\nclass CtrlC:\n    def reset(self, robot, pose):\n        self.pose = pose\n\n"
                    "    def update(self, readings):\n        signal.raise_signal(signal.SIGINT)\n")  # fmt: skip
    assert main(["evaluate", str(path), "--suite", "test", "--out", str(tmp_path / "out"), "--engine", "serial"]) == 130
    assert capsys.readouterr().err.strip().splitlines() == ["ctsim: interrupted"]


@given(st.one_of(st.floats(-1e307, 1e307), st.sampled_from([math.nan, math.inf, -math.inf])))  # (below the largest float, where "1.8e+308" would read back as inf)
def test_a_table_cell_stays_short_whatever_a_merged_file_holds(value):
    """A results file may hold any finite metric (1e300 m passes the merge's checks): its cell
    keeps 3 significant digits, thousands in full (1,266) and beyond a billion in exponent form,
    never hundreds of digits across the terminal; nan and inf print as a dash."""
    cell = _shown(value)
    assert len(cell) <= 13
    assert cell == "-" or math.isclose(float(cell.replace(",", "")), value, rel_tol=5e-3, abs_tol=1e-300)
