"""The rerun recording read back: truth, every estimate and the sensor series, in full."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pytest
from observers import KeepReadings

from bots.commands import WheelSpeeds
from bots.controller import FunctionController
from bots.ctbot import CTBOT
from sim.run import RobotSetup, run
from sim.views.recording import CHUNK, Recorder
from sim.world.files import load_world


def _columns(path) -> dict[str, dict[str, list]]:
    """Entity path -> column name -> values, temporal chunks concatenated in time order."""
    import rerun.chunk

    found: dict[str, dict[str, list]] = {}
    for chunk in rerun.chunk.RrdReader(path).stream().to_chunks():
        if chunk.is_static:
            continue
        columns = found.setdefault(chunk.entity_path, {})
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            column = batch.column(name)
            values = column.cast(pa.int64()).to_pylist() if name == "sim_time" else column.to_pylist()
            columns.setdefault(name, []).extend(values)
    for columns in found.values():
        order = np.argsort(columns["sim_time"], kind="stable")
        for name in columns:
            columns[name] = [columns[name][i] for i in order]
    return found


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "run.rrd"
    drive = FunctionController(lambda t, r: WheelSpeeds(0.12, 0.15))
    # more samples than one chunk, so that a chunk boundary is crossed
    keep = KeepReadings()
    result = run(load_world("maze"), [RobotSetup(CTBOT, drive)], duration=(CHUNK + 234) * 0.01, observers=[Recorder(path), keep])
    return result, _columns(path), keep.readings


def test_truth_trail_has_every_sample(recorded):
    result, columns, _ = recorded
    log = result.robots[0]
    truth = log.truth_array()
    strips = columns[f"/world/{log.name}/trail/truth"]["LineStrips2D:strips"]
    assert len(strips) == len(result.time) == len(truth)
    ends = np.array([row[0][1] for row in strips])
    np.testing.assert_allclose(ends, truth[:, :2], atol=1e-6)  # stored as float32
    starts = np.array([row[0][0] for row in strips])
    np.testing.assert_allclose(starts[1:], truth[:-1, :2], atol=1e-6)  # continuous across chunks
    times = np.array(columns[f"/world/{log.name}/body"]["sim_time"]) * 1e-9  # nanoseconds
    np.testing.assert_allclose(times, result.time, atol=1e-8)


def test_every_estimate_and_its_errors(recorded):
    result, columns, _ = recorded
    log = result.robots[0]
    truth = log.truth_array()
    assert log.estimate_arrays(), "the run loop should have estimators"
    for name, poses in log.estimate_arrays().items():
        ghost = np.array([row[0] for row in columns[f"/world/{log.name}/ghost/{name}"]["Points2D:positions"]])
        np.testing.assert_allclose(ghost, poses[:, :2], atol=1e-6)
        error = np.array(columns[f"/errors/{log.name}/position/{name}"]["Scalars:scalars"]).ravel()
        np.testing.assert_allclose(error, np.hypot(*(poses[:, :2] - truth[:, :2]).T), atol=1e-12)
        heading = np.array(columns[f"/errors/{log.name}/heading/{name}"]["Scalars:scalars"]).ravel()
        assert len(heading) == len(truth) and np.all(np.abs(heading) <= np.pi)


def test_sensor_series(recorded):
    result, columns, readings = recorded
    log = result.robots[0]
    for field, width in (("ir_raw", 2), ("encoder_ticks", 2), ("mouse_counts", 2), ("line", 2), ("light", 2)):
        rows = columns[f"/sensors/{log.name}/{field}"]["Scalars:scalars"]
        expected = np.array([getattr(r, field) for r in readings], dtype=float)
        assert np.array(rows).shape == (len(result.time), width)
        np.testing.assert_array_equal(np.array(rows), expected)
    rays = columns[f"/world/{log.name}/rays"]["LineStrips2D:strips"]
    assert len(rays) == len(result.time) and all(len(row) == len(CTBOT.ir) for row in rays)


def test_interrupted_run_is_still_readable(tmp_path):
    """A KeyboardInterrupt from inside the loop: the recorder flushes and closes the file."""
    path = tmp_path / "run.rrd"

    def drive(t, readings):
        if t >= 0.5:
            raise KeyboardInterrupt
        return WheelSpeeds(0.1, 0.1)

    result = run(load_world("maze"), [RobotSetup(CTBOT, FunctionController(drive))], duration=5.0, observers=[Recorder(path)])
    assert result.reason == "interrupted"
    body = _columns(path)[f"/world/{result.robots[0].name}/body"]
    assert len(body["Points2D:positions"]) == len(result.time)
