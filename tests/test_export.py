"""TUM and CSV trajectory files: format and round trips."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from bots.commands import Twist
from bots.controller import FunctionController
from bots.ctbot import CTBOT
from sim.analysis.export import TUM_HEADER, _tum_numbers, export_run, read_csv, read_tum, write_csv, write_tum
from sim.run.loop import RobotSetup, run
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
    assert path.read_text().splitlines() == ["t,x,y,theta", "0,0.5,0.25,0.125"]  # each float in its fewest exact digits


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
    import sim.run.samples
    from sim.analysis.export import write_run
    from sim.analysis.metrics import compare, compare_run

    robots = [RobotSetup(CTBOT, FunctionController(lambda t, r: Twist(0.1, 0.5))), RobotSetup(CTBOT, FunctionController(lambda t, r: Twist(0.2, -0.3)))]
    result = run(load_world("maze"), robots, 2.0)
    monkeypatch.setattr(sim.run.samples, "BLOCK", 37)
    monkeypatch.setattr("sim.analysis.export.FILE_ROWS", 37)
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


def test_parquet_holds_every_sample_of_poses_and_readings_across_blocks(tmp_path, monkeypatch):
    """`write_parquet` writes block by block (37 samples here, so 201 samples cross five edges):
    every pose and every reading of every sample comes back exactly, under its robot's name."""
    import sim.run.samples
    from sim.analysis.export import read_parquet, write_parquet
    from tests.observers import KeepReadings

    robots = [RobotSetup(CTBOT, FunctionController(lambda t, r: Twist(0.1, 0.5))), RobotSetup(CTBOT, FunctionController(lambda t, r: Twist(0.2, -0.3)))]
    keep = [KeepReadings(0), KeepReadings(1)]
    result = run(load_world("maze"), robots, 2.0, observers=keep)
    monkeypatch.setattr(sim.run.samples, "BLOCK", 37)
    monkeypatch.setattr("sim.analysis.export.FILE_ROWS", 37)
    table = read_parquet(write_parquet(result, tmp_path / "run.parquet"))
    assert np.array_equal(table["time"], result.time)
    for log, kept in zip(result.robots, keep):
        for label, poses in {"truth": log.truth_array(), **log.estimate_arrays()}.items():
            assert np.array_equal(np.column_stack([table[f"{log.name}.{label}.{axis}"] for axis in ("x", "y", "theta")]), poses)
        assert np.array_equal(table[f"{log.name}.encoder_ticks.right"], [r.encoder_ticks[1] for r in kept.readings])
        assert np.array_equal(table[f"{log.name}.mouse_counts.left"], [r.mouse_counts[1] for r in kept.readings])
        for field, sensors in (("ir_raw", CTBOT.ir), ("ir_distance", CTBOT.ir), ("line", CTBOT.line), ("border", CTBOT.border), ("light", CTBOT.light)):
            for k, sensor in enumerate(sensors):
                assert np.array_equal(table[f"{log.name}.{field}.{sensor.name}"], [getattr(r, field)[k] for r in kept.readings], equal_nan=True)


def test_an_export_rate_keeps_every_nth_sample_and_the_last(tmp_path, monkeypatch):
    """`write_run(every=10)` over blocks of 37 samples writes samples 0, 10, ..., 200 of 201 and
    the last (here sample 200 itself), byte for byte what the whole arrays give at those samples."""
    import sim.run.samples
    from sim.analysis.export import sampled, write_run

    result = run(load_world("maze"), [RobotSetup(CTBOT, FunctionController(lambda t, r: Twist(0.1, 0.5)))], 2.05)
    monkeypatch.setattr(sim.run.samples, "BLOCK", 37)
    monkeypatch.setattr("sim.analysis.export.FILE_ROWS", 37)
    written = write_run(result, tmp_path / "rate", prefix=False, with_csv=True, every=10)
    picked = np.r_[0 : len(result) : 10, len(result) - 1] if (len(result) - 1) % 10 else np.r_[0 : len(result) : 10]
    assert len(result) == 206 and picked[-1] == 205 and picked[-2] == 200  # the last sample, off the grid, is kept
    assert np.array_equal(np.concatenate([np.arange(len(result))[sampled(rows, len(result), 10)] for rows in result.blocks()]), picked)
    write_tum(tmp_path / "whole.tum", result.time[picked], result.robots[0].truth_array()[picked])
    assert written["ctbot"]["truth"].read_bytes() == (tmp_path / "whole.tum").read_bytes()


_TOKENS = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.floats(allow_nan=False, allow_infinity=False).map(lambda v: f"{v:+.17e}"),
    st.integers(-(10**30), 10**30).map(str),
    st.text("0123456789.eE+-", min_size=1, max_size=8),  # (mostly malformed: both must refuse it)
)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.lists(_TOKENS, min_size=7, max_size=9), min_size=1, max_size=6), st.booleans())
def test_tum_numbers_are_read_as_numpy_reads_them(lines: list[list[str]], header: bool) -> None:
    """Arrow's reader of plain TUM lines (`_tum_numbers`) gives np.loadtxt's floats bit for bit,
    and refuses what np.loadtxt refuses (a line of other than 8 numbers, a malformed one)."""
    text = (TUM_HEADER if header else "") + "".join(" ".join(line) + "\n" for line in lines)
    try:
        expected = np.loadtxt(io.StringIO(text), comments="#", ndmin=2)
    except ValueError:
        with pytest.raises(ValueError):
            _tum_numbers(text)
        return
    assert _tum_numbers(text).tobytes() == expected.tobytes()


def test_plain_tum_files_are_read_without_loadtxt(tmp_path, monkeypatch) -> None:
    """ctsim's own TUM files take the fast reader (np.loadtxt is not called); a file with tabs or
    a comment further down still reads, through np.loadtxt."""
    path = tmp_path / "t.tum"
    write_tum(path, np.array([0.0, 0.01, 0.02]), np.array([[1.0, 2.0, 0.1], [1.5, 2.5, 3.0], [1.6, 2.4, -3.0]]))
    expected = read_tum(path)
    (tmp_path / "tabs.tum").write_text(path.read_text().replace(" ", "\t") + "# the end\n")
    assert all(np.array_equal(a, b) for a, b in zip(read_tum(tmp_path / "tabs.tum"), expected))
    (tmp_path / "blank.tum").write_text(TUM_HEADER + "\n\n")  # (no pose: refused as np.loadtxt's (0, 1) rows are)
    with pytest.raises(ValueError, match="8 numbers"):
        read_tum(tmp_path / "blank.tum")
    monkeypatch.setattr(np, "loadtxt", lambda *args, **named: pytest.fail("np.loadtxt called for a plain TUM file"))
    assert all(np.array_equal(a, b) for a, b in zip(read_tum(path), expected))
