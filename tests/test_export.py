"""TUM and CSV trajectory files: format and round trips."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from bots.commands import Twist
from bots.controller import FunctionController
from bots.ctbot import CTBOT
from sim.analysis.export import export_run, read_csv, read_tum, write_csv, write_tum
from sim.run import RobotSetup, run
from sim.world.files import load_world

finite = st.floats(-1e3, 1e3, allow_nan=False)


@st.composite
def trajectories(draw) -> tuple[np.ndarray, np.ndarray]:
    """Times and poses with a continuous heading (steps below pi, so unwrapping recovers it)."""
    n = draw(st.integers(1, 30))
    times = np.cumsum(draw(arrays(np.float64, n, elements=st.floats(0, 10))))
    xy = draw(arrays(np.float64, (n, 2), elements=finite))
    turns = draw(arrays(np.float64, n, elements=st.floats(-3.0, 3.0)))
    return times, np.column_stack((xy, np.cumsum(turns)))


@settings(max_examples=40)
@given(trajectories())
def test_tum_round_trip(tmp_path_factory, trajectory):
    times, poses = trajectory
    path = tmp_path_factory.mktemp("tum") / "t.tum"
    write_tum(path, times, poses)
    read_times, read_poses = read_tum(path)
    assert np.array_equal(read_times, times)
    assert np.array_equal(read_poses[:, :2], poses[:, :2])
    # heading through the quaternion: unwrapping is relative to the first heading's wrapped value
    assert np.allclose(np.diff(read_poses[:, 2]), np.diff(poses[:, 2]), atol=1e-9)
    assert np.allclose(np.cos(read_poses[:, 2] - poses[:, 2]), 1.0)


@settings(max_examples=40)
@given(trajectories())
def test_csv_round_trip_is_exact(tmp_path_factory, trajectory):
    times, poses = trajectory
    path = tmp_path_factory.mktemp("csv") / "t.csv"
    write_csv(path, times, poses, {"speed": poses[:, 0] * 0.5})
    read_times, read_poses, extra = read_csv(path)
    assert np.array_equal(read_times, times) and np.array_equal(read_poses, poses)
    assert list(extra) == ["speed"] and np.array_equal(extra["speed"], poses[:, 0] * 0.5)


def test_tum_lines_are_what_evo_reads(tmp_path):
    path = tmp_path / "t.tum"
    write_tum(path, np.array([0.0, 0.01]), np.array([[1.0, 2.0, 0.0], [1.5, 2.5, math.pi / 2]]))
    lines = [line.split() for line in path.read_text().splitlines() if not line.startswith("#")]
    assert [len(line) for line in lines] == [8, 8]
    values = np.array(lines, dtype=float)
    assert np.allclose(values[1], [0.01, 1.5, 2.5, 0, 0, 0, math.sin(math.pi / 4), math.cos(math.pi / 4)])
    assert np.allclose(values[0, 4:], [0, 0, 0, 1])


def test_csv_header(tmp_path):
    path = tmp_path / "t.csv"
    write_csv(path, np.array([0.0]), np.array([[0.5, 0.25, 0.125]]))
    assert path.read_text().splitlines() == ["t,x,y,theta", "0.0,0.5,0.25,0.125"]


def test_bad_files_and_shapes_are_refused(tmp_path):
    with pytest.raises(ValueError, match="T times"):
        write_tum(tmp_path / "a.tum", np.zeros(2), np.zeros((3, 3)))
    (tmp_path / "b.tum").write_text("0 1 2 3\n")
    with pytest.raises(ValueError, match="8 numbers"):
        read_tum(tmp_path / "b.tum")
    (tmp_path / "c.tum").write_text("0 1 2 0.5 0 0 0 1\n")
    with pytest.raises(ValueError, match="not planar"):
        read_tum(tmp_path / "c.tum")
    (tmp_path / "d.csv").write_text("time,x\n0,1\n")
    with pytest.raises(ValueError, match="t,x,y,theta"):
        read_csv(tmp_path / "d.csv")


def test_export_run_writes_truth_and_every_estimate(tmp_path):
    result = run(load_world("empty"), [RobotSetup(CTBOT, FunctionController(lambda t, r: Twist(0.1, 0.5)))], 0.5)
    paths = export_run(result, tmp_path / "out")
    assert sorted(p.name for p in paths) == sorted(
        f"ctbot_{label}.tum" for label in ("truth", "encoders", "firmware", "mouse", "fused")
    )
    times, truth = read_tum(tmp_path / "out" / "ctbot_truth.tum")
    assert np.array_equal(times, result.time)
    assert np.allclose(truth, result.robots[0].truth_array(), atol=1e-12)


def test_a_run_written_in_blocks_equals_its_arrays_written_at_once(tmp_path, monkeypatch):
    """`write_run` reads a run through in blocks (here 37 samples, so the 201 samples of two robots
    cross five block edges): every file is byte for byte what the whole arrays give, and the
    metrics read through the same way equal those of the whole arrays (regrouped sums of squares:
    1e-12 relative)."""
    import sim.run
    from sim.analysis.export import write_run
    from sim.analysis.metrics import compare, compare_run

    robots = [RobotSetup(CTBOT, FunctionController(lambda t, r: Twist(0.1, 0.5))), RobotSetup(CTBOT, FunctionController(lambda t, r: Twist(0.2, -0.3)))]
    result = run(load_world("maze"), robots, 2.0)
    monkeypatch.setattr(sim.run, "BLOCK", 37)
    written = write_run(result, tmp_path / "blocks", prefix=True, with_csv=True)
    metrics = compare_run(result)
    for log in result.robots:
        for label, poses in {"truth": log.truth_array(), **log.estimate_arrays()}.items():
            tum = written[log.name][label]
            write_tum(tmp_path / "whole.tum", result.time, poses)
            write_csv(tmp_path / "whole.csv", result.time, poses)
            assert tum.read_bytes() == (tmp_path / "whole.tum").read_bytes()
            assert tum.with_suffix(".csv").read_bytes() == (tmp_path / "whole.csv").read_bytes()
            if label != "truth":
                whole = compare(result.time, log.truth_array(), poses)
                assert metrics[log.name][label].ate_rmse == pytest.approx(whole.ate_rmse, rel=1e-12)
                assert metrics[log.name][label].path_length == whole.path_length
