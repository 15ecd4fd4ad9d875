"""The Python API: worlds and robots by name, robot changes by dotted name, results as arrays and
frames, recordings, the examples of docs/experiments.md, and sweep plans (grid, random, ids)."""

from __future__ import annotations

import re
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from bots.commands import Twist
from bots.ctbot import CTBOT
from sim.experiments import Bot, SpecError, change_robot, simulate, spec_from_dict
from sim.experiments.plan import jobs, run_id, settings

EXPERIMENTS = Path(__file__).resolve().parents[1] / "docs" / "experiments.md"


def test_simulate_gives_arrays_and_metrics():
    result = simulate("square", Bot("square", params={"side_m": 0.3}), duration=1.0, seed=2)
    robot = result.robots[0]
    assert result.reason == "duration" and result.error is None
    assert result.time.shape == (101,)  # 1 s at 10 ms, both ends
    assert robot.truth.shape == (101, 3)
    assert set(robot.estimates) == {"encoders", "firmware", "mouse", "fused"}
    assert all(poses.shape == (101, 3) for poses in robot.estimates.values())
    frame = result.metrics_frame()
    assert list(frame["estimator"]) == list(robot.estimates)
    assert frame.loc[frame.estimator == "mouse", "ate_rmse"].item() == robot.metrics["mouse"]["ate_rmse"]


def test_a_robot_result_pickles_with_its_arrays():
    """A robot's result crosses to another process (pickle, as multiprocessing and joblib send it)
    with its trajectories and metrics, though its log's samples live in an open file."""
    import pickle

    robot = simulate("square", Bot("square"), duration=0.5, seed=3).robots[0]
    copy = pickle.loads(pickle.dumps(robot))
    assert copy.log is None and copy.distance == robot.distance
    np.testing.assert_equal(copy.metrics, robot.metrics)  # (nan where a metric has no value: equal here)
    np.testing.assert_array_equal(copy.truth, robot.truth)
    assert all(np.array_equal(copy.estimates[k], robot.estimates[k]) for k in robot.estimates)
    assert all(np.array_equal(copy.covariances[k], robot.covariances[k]) for k in robot.covariances)


class _Drifts:
    """A Python estimator (its poses in columns of its robot's own), whose object stays behind."""

    name = "drifts"

    def reset(self, robot, pose):
        self.pose = np.array(pose, dtype=float)
        self.lock = threading.Lock()  # (cannot be pickled)

    def update(self, readings):
        self.pose = self.pose + 1e-4


def test_a_whole_result_pickles_with_its_samples_and_reads_them_back_alike():
    """A whole result crosses to another process (pickle, as multiprocessing and joblib send it)
    with the samples its run's file held (no file: the copy reads them from its bytes), without
    the world and the estimators' objects (live simulation, user code): the same times, summary,
    metrics, trajectories of the batch's and of a robot's own columns, and readings, read-only."""
    import pickle

    result = simulate("square", Bot("square"), Bot("wander", start=(0.5, 0.5, 0.0)), duration=0.5, seed=3, estimators=[_Drifts])
    copy = pickle.loads(pickle.dumps(result))
    assert copy.reason == result.reason and np.array_equal(copy.time, result.time) and not copy.raw.time.flags.writeable
    np.testing.assert_equal(copy.summary(), result.summary())  # (nan where a metric has no value: equal here)
    assert copy.metrics_frame().equals(result.metrics_frame())
    for mine, theirs in zip(result.raw.robots, copy.raw.robots):
        assert theirs.estimators == [] and "drifts" in theirs.estimate_names
        np.testing.assert_equal(theirs.truth_array(), mine.truth_array())
        np.testing.assert_equal(theirs.estimate_arrays(), mine.estimate_arrays())
        np.testing.assert_equal(theirs.covariance_arrays(), mine.covariance_arrays())
        np.testing.assert_equal(theirs.readings(slice(None)), mine.readings(slice(None)))
    np.testing.assert_equal(copy.robots[1].estimates, result.robots[1].estimates)
    again = pickle.loads(pickle.dumps(copy))  # (a copy sent on again)
    np.testing.assert_equal(again.raw.robots[1].readings(slice(2, 9)), result.raw.robots[1].readings(slice(2, 9)))


def test_same_seed_same_trajectory_and_controller_objects():
    noisy = {"encoders.slip_std": 0.05}
    a = simulate("empty", Bot(lambda t, r: Twist(0.2, 1.0), changes=noisy), duration=0.5, seed=7)
    b = simulate("empty", Bot(lambda t, r: Twist(0.2, 1.0), changes=noisy), duration=0.5, seed=7)
    c = simulate("empty", Bot(lambda t, r: Twist(0.2, 1.0), changes=noisy), duration=0.5, seed=8)
    assert np.array_equal(a.robots[0].truth, b.robots[0].truth)
    assert not np.array_equal(a.robots[0].truth, c.robots[0].truth)  # slip moves the body, drawn per seed


def test_robots_as_a_list_and_noise_as_the_command_line_gives_them():
    """`simulate(world, [bots])` or `robots=[...]` (`--robots`), `noise=` (`--noise`) for every Bot
    that names none of its own."""
    listed = simulate("maze", [Bot("idle"), Bot("wander")], duration=0.1)
    keyword = simulate("maze", robots=[Bot("idle")] * 3, duration=0.1)
    assert [r.controller for r in listed.robots] == ["idle", "wander"] and len(keyword.robots) == 3
    quiet = simulate("empty", Bot("wander"), noise="none", duration=0.5, seed=3)
    noisy = simulate("empty", Bot("wander"), noise="realistic", duration=0.5, seed=3)
    own = simulate("empty", Bot("wander", noise="none"), noise="realistic", duration=0.5, seed=3)
    assert not np.array_equal(quiet.robots[0].truth, noisy.robots[0].truth)  # realistic slip moves the body
    assert np.array_equal(quiet.robots[0].truth, own.robots[0].truth)
    assert (quiet.summary()["noise"], noisy.summary()["noise"], own.summary()["noise"]) == ("none", "realistic", "none")
    mixed = simulate("empty", [Bot("idle", noise="harsh"), Bot("idle")], duration=0.1)
    assert mixed.summary()["noise"] == "harsh, realistic"
    with pytest.raises(TypeError, match="a Bot or a RobotSetup, got str"):
        simulate("empty", "wander")
    with pytest.raises(ValueError, match="unknown noise preset"):
        simulate("empty", Bot("wander"), noise="loud")


def test_simulate_runs_with_the_command_lines_noise_by_default():
    """`simulate` and `ctsim run` mean the same physics: realistic noise unless told otherwise,
    named in the summary (and so in the notebook's table of facts)."""
    from bots.noise import DEFAULT_NOISE
    from sim.views.html import run_facts

    default = simulate("empty", Bot("wander"), duration=0.5, seed=3)
    named = simulate("empty", Bot("wander"), noise=DEFAULT_NOISE, duration=0.5, seed=3)
    assert DEFAULT_NOISE == "realistic"
    assert np.array_equal(default.robots[0].truth, named.robots[0].truth)
    assert default.summary()["noise"] == "realistic" and run_facts(default.summary())["noise"] == "realistic"


def test_failing_controller_is_a_result_not_an_exception():
    def broken(t, readings):
        raise ZeroDivisionError("oops")

    result = simulate("empty", Bot(broken), duration=1.0)
    assert result.reason == "error" and "ZeroDivisionError" in result.error
    assert len(result.robots[0].truth) == 1  # the first sample is kept


def test_change_robot_by_dotted_name():
    changed = change_robot(CTBOT, {"encoders.slip_std": 0.02, "ir.noise_std": 0.01, "encoders.diameter_error": [0.01, -0.01], "mass": 1.0})
    assert changed.encoders.slip_std == 0.02 and changed.encoders.diameter_error == (0.01, -0.01)
    assert all(s.noise_std == 0.01 for s in changed.ir) and changed.mass == 1.0
    assert CTBOT.encoders.slip_std == 0.0  # a copy
    with pytest.raises(ValueError, match="no field 'slipp'"):
        change_robot(CTBOT, {"encoders.slipp": 0.1})


def test_recording_is_written(tmp_path):
    from rerun.chunk import RrdReader  # noqa: F401  (rerun 0.41 reads recordings back)

    simulate("empty", Bot("idle"), duration=0.2, record=tmp_path / "run.rrd")
    assert (tmp_path / "run.rrd").stat().st_size > 0


def test_readme_examples_run(tmp_path, monkeypatch):
    """Every ```python block of docs/experiments.md runs as written, except the dask-jobqueue one,
    which needs a SLURM cluster."""
    section = EXPERIMENTS.read_text(encoding="utf-8")
    blocks = [b for b in re.findall(r"```python\n(.*?)```", section, re.S) if "dask_jobqueue" not in b]
    assert len(blocks) == 3
    monkeypatch.chdir(tmp_path)
    for block in blocks:
        exec(compile(block, str(EXPERIMENTS), "exec"), {"__name__": "__main__"})


def test_sweep_is_the_function_after_its_module_was_imported_directly():
    """Importing a package's submodule binds it as the package's attribute: a submodule named
    `sweep` replaced the public function for every later `from sim.experiments import sweep`
    (test_readme_examples_run failed right after test_evaluate.py). In a fresh interpreter, so
    that no earlier import in this process decides it."""
    code = "import sim.experiments.sweeping, sim.experiments.evaluation\nfrom sim.experiments import sweep\nprint(callable(sweep), type(sweep).__name__)"
    shown = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert shown.stdout.split() == ["True", "function"]


def test_grid_plan_and_ids():
    spec = spec_from_dict({"base": {"duration": 1.0}, "axes": {"seed": [0, 1, 2], "world": ["maze", "empty"]}})
    planned = settings(spec)
    assert len(planned) == 6 and planned[1] == {**planned[1], "seed": 0, "world": "empty"}  # last axis fastest
    assert run_id({"a": 1, "b": 2}) == run_id({"b": 2, "a": 1})
    assert len({job.run_id for job in jobs(spec)}) == 6


def test_a_noise_axis_runs_each_preset_and_names_it_in_its_row():
    """`noise` is a sweep setting as `--noise` is an option: realistic unless [base] or [axes] say
    otherwise; each preset gives the same run as `simulate(noise=...)`."""
    from sim.experiments.sweeping import execute

    assert all(s["noise"] == "realistic" for s in settings(spec_from_dict({"axes": {"seed": [0, 1]}})))
    spec = spec_from_dict({"base": {"duration": 0.3, "world": "empty", "controller": "wander", "seed": 3}, "axes": {"noise": ["none", "realistic", "harsh"]}})
    rows = [execute(job) for job in jobs(spec)]
    assert [row["noise"] for row in rows] == ["none", "realistic", "harsh"] and all(row["error"] is None for row in rows)
    for row in rows:
        alone = simulate("empty", Bot("wander"), noise=row["noise"], duration=0.3, seed=3)
        assert row["distance"] == alone.robots[0].distance
    assert len({row["distance"] for row in rows}) == 3  # three presets, three different runs
    with pytest.raises(SpecError, match="noise: must be one of 'none', 'realistic', 'harsh'"):
        spec_from_dict({"base": {"noise": "loud"}})


def test_random_plan_is_reproducible_and_extends():
    axes = {"robot.encoders.slip_std": {"log_uniform": [0.001, 0.1]}, "seed": {"integers": [0, 9]}, "world": ["maze", "empty"]}
    small = settings(spec_from_dict({"sweep": {"mode": "random", "samples": 5, "seed": 3}, "axes": axes}))
    large = settings(spec_from_dict({"sweep": {"mode": "random", "samples": 9, "seed": 3}, "axes": axes}))
    assert large[:5] == small
    assert all(0.001 <= s["robot.encoders.slip_std"] <= 0.1 and 0 <= s["seed"] <= 9 for s in large)


@pytest.mark.parametrize(
    "data, message",
    [
        ({"axes": {"colour": [1]}}, "unknown setting 'colour'"),
        ({"axes": {"seed": 3}}, "must be a list"),
        ({"axes": {"seed": {"uniform": [0, 1]}}}, "need mode"),
        ({"sweep": {"mode": "random"}}, "samples"),
        ({"sweep": {"mode": "random", "samples": 2}, "axes": {"dt": {"log_uniform": [0, 1]}}}, "positive bounds"),
        ({"base": {"seed": 1}, "axes": {"seed": [1, 2]}}, "both"),
        ({"runs": {}}, "unknown table"),
    ],
)
def test_spec_mistakes_name_the_key(data, message):
    with pytest.raises(SpecError, match=message):
        spec_from_dict(data, "spec.toml")

