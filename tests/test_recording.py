"""The rerun recording read back: truth, every estimate, the sensor series, events, and a blueprint
whose every view and override names something the recording logs."""

from __future__ import annotations

import signal
import socket
import threading

import numpy as np
import pyarrow as pa
import pytest
from observers import KeepReadings

from bots.commands import WheelSpeeds
from bots.controller import FunctionController
from bots.ctbot import CTBOT
from sim.run.loop import RobotSetup, run
from sim.views.recording.layout import BAND_LABEL, TRAIL_EVERY
from sim.views.recording.recorder import CHUNK, Recorder
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
            if name in ("log_time", "log_tick"):  # rerun's own wall-clock timelines of `log` calls
                continue
            column = batch.column(name)
            values = column.cast(pa.int64()).to_pylist() if name == "sim_time" else column.to_pylist()
            columns.setdefault(name, []).extend(values)
    for columns in found.values():
        order = np.argsort(columns["sim_time"], kind="stable")
        for name in columns:
            columns[name] = [columns[name][i] for i in order]
    return found


def _entities(path) -> set[str]:
    """Every entity path the recording logs data at (static or temporal)."""
    import rerun.chunk

    return {chunk.entity_path for chunk in rerun.chunk.RrdReader(path).stream().to_chunks()}


def _blueprint_columns(path) -> dict[str, dict[str, list]]:
    """The recording's own blueprint store: entity path -> column -> its last value."""
    import rerun.chunk

    reader = rerun.chunk.RrdReader(path)
    (store,) = reader.blueprints()
    found: dict[str, dict[str, list]] = {}
    for chunk in reader.stream(store=store).to_chunks():
        batch = chunk.to_record_batch()
        found.setdefault(chunk.entity_path, {}).update({name: batch.column(name).to_pylist()[-1] for name in batch.schema.names})
    return found


def _blueprint(path) -> tuple[list[tuple[str, list[str]]], list[str]]:
    """(origin, queries) of each view of the recording's blueprint, and the entity path of every override."""
    columns = _blueprint_columns(path)
    views = [(values["ViewBlueprint:space_origin"][0], columns[f"{where}/ViewContents"]["ViewContents:query"]) for where, values in columns.items()
             if "ViewBlueprint:space_origin" in values]  # fmt: skip
    overrides = ["/" + where.split("/ViewContents/overrides/", 1)[1].removesuffix("/visualizers") for where in columns if "/ViewContents/overrides/" in where]
    return views, overrides


def _view_names(path) -> list[tuple[str, str]]:
    """(title, origin) of each view of the recording's blueprint."""
    columns = _blueprint_columns(path)
    return [(values["ViewBlueprint:display_name"][0], values["ViewBlueprint:space_origin"][0]) for values in columns.values() if "ViewBlueprint:space_origin" in values]


def _legends_shown(path) -> dict[str, bool]:
    """Origin of each plot with a legend setting -> whether its legend shows (rerun's default: it does)."""
    columns = _blueprint_columns(path)
    return {columns[where.removesuffix("/PlotLegend")]["ViewBlueprint:space_origin"][0]: values.get("PlotLegend:visible", [True])[0]
            for where, values in columns.items() if where.endswith("/PlotLegend")}  # fmt: skip


def _static(path, entity: str) -> dict[str, list]:
    """The static columns of one entity: column -> its values."""
    import rerun.chunk

    found: dict[str, list] = {}
    for chunk in rerun.chunk.RrdReader(path).stream().to_chunks():
        if chunk.is_static and chunk.entity_path == entity:
            batch = chunk.to_record_batch()
            found.update({name: batch.column(name).to_pylist()[-1] for name in batch.schema.names})
    return found


def _names_logged(path_expression: str, entities: set[str]) -> bool:
    """Whether an entity path (or `path/**` subtree) holds something the recording logs."""
    root = path_expression.removesuffix("/**").rstrip("/") or "/"
    return any(e == root or e.startswith(root.rstrip("/") + "/") for e in entities)


def _drive(t, readings):
    return WheelSpeeds(0.12, 0.15)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "run.rrd"
    # more samples than one chunk, and not a whole number of trail pieces
    keep = KeepReadings()
    result = run(load_world("maze"), [RobotSetup(CTBOT, FunctionController(_drive))], duration=(CHUNK + 234) * 0.01, observers=[Recorder(path), keep])
    result.readings_seen = keep.readings  # the run loop keeps only the current readings
    return result, path, _columns(path)


def test_truth_pose_and_trail_have_every_sample(recorded):
    result, _, columns = recorded
    log = result.robots[0]
    truth = log.truth_array()
    body = columns[f"/world/{log.name}/body"]
    assert len(body["Transform3D:translation"]) == len(result.time) == len(truth)
    np.testing.assert_allclose(np.array(body["Transform3D:translation"])[:, 0, :2], truth[:, :2], atol=1e-6)  # float32
    times = np.array(body["sim_time"]) * 1e-9  # nanoseconds
    np.testing.assert_allclose(times, result.time, atol=1e-8)
    pieces = columns[f"/world/{log.name}/trail/truth"]["LineStrips2D:strips"]
    assert len(pieces) == -(-len(truth) // TRAIL_EVERY)  # one piece per TRAIL_EVERY samples, the last shorter
    joined = np.concatenate([np.array(row[0])[1:] for row in pieces])  # each piece starts at the last one's end
    np.testing.assert_allclose(joined, truth[1:, :2], atol=1e-6)


def test_every_estimate_and_its_errors_in_mm_and_degrees(recorded):
    result, _, columns = recorded
    log = result.robots[0]
    truth = log.truth_array()
    assert log.estimate_arrays(), "the run loop should have estimators"
    errors = np.array(columns[f"/errors/{log.name}/position"]["Scalars:scalars"])  # (samples, estimates): a series each
    headings = np.array(columns[f"/errors/{log.name}/heading"]["Scalars:scalars"])
    assert errors.shape == headings.shape == (len(truth), len(log.estimate_arrays()))
    for k, (name, poses) in enumerate(log.estimate_arrays().items()):
        where = np.array(columns[f"/world/{log.name}/estimate/{name}"]["Transform3D:translation"])[:, 0, :2]
        np.testing.assert_allclose(where, poses[:, :2], atol=1e-6)  # rerun keeps translations in float32: 2e-7 m at 3 m
        np.testing.assert_allclose(errors[:, k], 1000 * np.hypot(*(poses[:, :2] - truth[:, :2]).T), atol=1e-9)
        assert np.all(np.abs(headings[:, k]) <= 180.0)


def test_sensor_series_grouped_by_sensor(recorded):
    result, _, columns = recorded
    log = result.robots[0]
    readings = result.readings_seen
    for group, field, scale in (("ir_raw", "ir_raw", 1), ("ir_distance", "ir_distance", 1000), ("encoders", "encoder_ticks", 1), ("mouse", "mouse_counts", 1), ("floor", "line", 1),
                                ("floor", "border", 1), ("light", "light", 1)):
        rows = np.array(columns[f"/sensors/{group}/{log.name}/{field}"]["Scalars:scalars"], dtype=float)
        expected = np.array([getattr(r, field) for r in readings], dtype=float) * scale
        assert rows.shape == expected.shape == (len(result.time), 2)
        np.testing.assert_array_equal(rows, expected)
    rays = columns[f"/world/{log.name}/rays"]["LineStrips2D:strips"]
    assert len(rays) == len(result.time) and all(len(row) == len(CTBOT.ir) for row in rays)


@pytest.mark.parametrize("robots", [1, 3])
def test_blueprint_names_only_what_is_logged(tmp_path, robots):
    path = tmp_path / "run.rrd"
    setups = [RobotSetup(CTBOT, FunctionController(_drive), start=(0.36 + 0.24 * k, 0.36, 0.0)) for k in range(robots)]
    run(load_world("maze"), setups, duration=0.5, observers=[Recorder(path)])
    entities = _entities(path)
    views, overrides = _blueprint(path)
    assert len(views) >= 2 + 2 * robots + 6  # map, events, facts, two error plots per robot, six sensor groups
    sensor_views = [origin for origin, _ in views if origin.startswith("/sensors/")]
    if robots > 1:  # one plot per robot and sensor kind: no plot mixes robots
        assert sorted(sensor_views) == sorted(f"/sensors/{group}/{name}" for group in ("ir_raw", "ir_distance", "floor", "light", "encoders", "mouse")
                                              for name in ("ctbot", "ctbot1", "ctbot2"))  # fmt: skip
        named = [e for e in entities if e.endswith("/body/name")]
        assert sorted(named) == ["/world/ctbot/body/name", "/world/ctbot1/body/name", "/world/ctbot2/body/name"]
    for origin, queries in views:
        for query in queries:
            expression = query.removeprefix("+ ").replace("$origin", origin.rstrip("/"))
            assert _names_logged(expression, entities), f"view at {origin} queries {query}: nothing logged there"
    trails = [o for o in overrides if "/trail/" in o]
    assert len(trails) == robots * 5  # truth and four estimates each
    for override in overrides:
        assert override in entities, f"override on {override}, which holds no data"


@pytest.mark.parametrize("robots, estimates", [(1, True), (3, True), (2, False)])
def test_the_maps_key_names_the_error_plots_series_whose_legends_stay_hidden(tmp_path, robots, estimates):
    """Up to twelve series would bury an error plot under its legend: the key beside the map holds
    each trail's and series' colour under its name (an estimate once, its colour being every
    robot's), and the error plots show no legend; a robot without estimates (a contest's) is keyed
    by its truth only."""
    path = tmp_path / "run.rrd"
    setups = [RobotSetup(CTBOT, FunctionController(_drive), start=(0.36 + 0.24 * k, 0.36, 0.0), estimators=None if estimates else []) for k in range(robots)]
    result = run(load_world("maze"), setups, duration=0.3, observers=[Recorder(path)])
    key, swatches = _static(path, "/world/map/key/labels"), _static(path, "/world/map/key/lines")
    colour = dict(zip(key["Points2D:labels"], swatches["LineStrips2D:colors"]))
    assert len(colour) == len(key["Points2D:labels"]) == len(swatches["LineStrips2D:colors"])  # each label once, each with its swatch's colour
    assert len(key["Points2D:colors"]) == 1, "every label in one text colour (a series' colour as text is hard to read)"
    rows = [y for (_, y), _ in swatches["LineStrips2D:strips"]]
    for (x, y), ((left, top), (right, _)) in zip(key["Points2D:positions"], swatches["LineStrips2D:strips"]):
        nearest = min(rows, key=lambda row: abs(row - y))
        assert left < x < right and y < top == nearest, "a label hangs under the middle of its own swatch (rerun centres a label under its point)"
    truths = [log.name for log in result.robots] if robots > 1 else ["truth"]
    assert key["Points2D:labels"][:robots] == truths
    for log, truth in zip(result.robots, truths):
        assert [colour[truth]] == _static(path, f"/world/{log.name}/trail/truth")["LineStrips2D:colors"]
    (framed,) = [values["VisualBounds2D:range"][0] for values in _blueprint_columns(path).values() if "VisualBounds2D:range" in values]
    xmin, ymin, xmax, ymax = load_world("maze").bounds
    for x, y in [*key["Points2D:positions"], *(point for line in _static(path, "/world/map/key/lines")["LineStrips2D:strips"] for point in line)]:
        assert xmax < x < framed["x_range"][1] and ymin < y <= ymax + 1e-6, "the key lies in the map view, beside the world"  # (float32 positions)
    labels = list(result.robots[0].estimate_arrays())
    assert key["Points2D:labels"][robots:] == ([*labels, BAND_LABEL] if estimates else [])
    legends = _legends_shown(path)
    for log in result.robots:
        for label in labels:  # the map's trail in the key's colour
            assert [colour[label]] == _static(path, f"/world/{log.name}/trail/{label}")["LineStrips2D:colors"]
        for plot in ("position", "heading"):  # each plot series in the key's colour, under its name
            series = _static(path, f"/errors/{log.name}/{plot}")
            assert series.get("SeriesLines:names", []) == [f"{log.name} {label}" if robots > 1 else label for label in labels]
            assert series.get("SeriesLines:colors", []) == [colour[label] for label in labels]
            assert legends.get(f"/errors/{log.name}/{plot}", False) is False, "an error plot shows its legend"
    assert any(origin.startswith("/errors/") for origin in legends) == estimates
    titles = {origin: name for name, origin in _view_names(path)}
    for log in result.robots:  # the first estimate wide beneath the rest, said in the title: one equal to it stays in sight
        for plot in ("position", "heading") if estimates else ():
            widths = _static(path, f"/errors/{log.name}/{plot}")["SeriesLines:widths"]
            assert widths[0] >= widths[1] + 2.5 and len(set(widths[1:])) == 1, "a line 1.2 points wide on one of 4: 1.4 points of the first's colour each side"
            assert f"{labels[0]} wide beneath" in titles[f"/errors/{log.name}/{plot}"]
    sensor_plots = [shown for origin, shown in legends.items() if origin.startswith("/sensors/")]
    assert sensor_plots and all(sensor_plots)  # their two to four series keep their small legends...
    for log in result.robots:  # ...of the channels' names only: each robot has plots of its own
        assert _static(path, f"/sensors/ir_raw/{log.name}/ir_raw")["SeriesLines:names"] == ["ir_left", "ir_right"]


def _packed(colour) -> int:
    """An RGB tuple as rerun stores a colour (0xRRGGBBAA, opaque)."""
    r, g, b = colour
    return (r << 24) | (g << 16) | (b << 8) | 0xFF


@pytest.mark.parametrize("robots", [1, 3])
def test_the_maps_labels_are_light_text_over_hidden_points_and_every_swatch_has_a_dark_rim(tmp_path, robots):
    """rerun writes a point's label in the point's colour on a translucent grey box: a red or white
    robot's name, a series' name, were hard to read there. Every label of the map (the key's, the
    robots' names) is light text whose point lies beneath what covers it (a swatch, the floor); each
    swatch has a dark rim, so that a white or yellow robot's shows on the light grey beside the map."""
    from sim.views import palette

    path = tmp_path / "run.rrd"
    setups = [RobotSetup(CTBOT, FunctionController(_drive), start=(0.36 + 0.24 * k, 0.36, 0.0)) for k in range(robots)]
    result = run(load_world("maze"), setups, duration=0.3, observers=[Recorder(path)])
    light = [_packed(palette.LABEL_TEXT)]
    floor = _static(path, "/world/map/floor")["EncodedImage:draw_order"][0]
    names = [_static(path, f"/world/{log.name}/body/name") for log in result.robots] if robots > 1 else []
    assert [name["Points2D:labels"] for name in names] == [[log.name] for log in result.robots[: len(names)]]
    for name in names:
        assert name["Points2D:colors"] == light and name["Points2D:draw_order"][0] < floor
    assert robots == 1 or palette.ROBOTS[2] == (250, 250, 250), "the third robot is white (this test's case for the rim)"
    key, swatches, edges = (_static(path, f"/world/map/key/{part}") for part in ("labels", "lines", "edges"))
    assert key["Points2D:colors"] == light
    assert edges["LineStrips2D:strips"] == swatches["LineStrips2D:strips"] and edges["LineStrips2D:colors"] == [_packed(palette.KEY_EDGE)]
    for rim, width in zip(edges["LineStrips2D:radii"], swatches["LineStrips2D:radii"]):
        assert rim <= width - 1.0 < 0, "a rim a point wide round each swatch (negative radii: points on screen)"
    assert key["Points2D:draw_order"][0] < edges["LineStrips2D:draw_order"][0] < swatches["LineStrips2D:draw_order"][0]
    assert max(palette.KEY_EDGE) < 64 and min(palette.LABEL_TEXT) > 192, "a dark rim; light text"


def test_map_view_shows_the_y_flip(recorded):
    """The flip is logged on /world; the map view must look at /world's content from above it."""
    import rerun.chunk

    _, path, _ = recorded
    flips = []
    for chunk in rerun.chunk.RrdReader(path).stream().to_chunks():
        batch = chunk.to_record_batch()
        if "Transform3D:scale" in batch.schema.names and chunk.entity_path.count("/") == 1:
            flips += [(chunk.entity_path, scale) for (scale,) in batch.column("Transform3D:scale").to_pylist()]
    assert flips == [("/world", [1.0, -1.0, 1.0])]
    views, _ = _blueprint(path)
    (origin, queries), = [(o, q) for o, q in views if any("/world" in query for query in q)]
    assert "/world".startswith(origin.rstrip("/") + "/") or origin == "/"  # the view's space is above the flip
    assert queries == ["+ /world/**"]


def test_events_say_start_collision_and_end(tmp_path):
    path = tmp_path / "run.rrd"
    result = run(load_world("maze"), [RobotSetup(CTBOT, FunctionController(lambda t, r: WheelSpeeds(0.3, 0.3)))], duration=4.0, observers=[Recorder(path)])
    assert result.robots[0].collisions >= 1  # straight ahead from the start meets the wall
    text = [row[0] for row in _columns(path)["/events"]["TextLog:text"]]
    assert text[0].startswith("start: ctbot") and text[-2:] == ["ctbot: goal not reached in 4 s", "end: duration"]
    assert sum("collision" in line for line in text) == result.robots[0].collisions


def test_a_goal_reached_is_one_event_when_it_happens(tmp_path):
    """The goal said once, at its time, in the words of the table ('goal reached at 0.0 s'); the
    end's outcome line is for a robot that did not reach it (the test above)."""
    path = tmp_path / "run.rrd"
    goal_tile = (3.0, 2.76, 0.0)  # the shipped maze's goal ('Z', as tests/test_goal_report.py)
    run(load_world("maze"), [RobotSetup(CTBOT, FunctionController(lambda t, r: WheelSpeeds(0.0, 0.0)), start=goal_tile)], duration=0.5, observers=[Recorder(path)])
    events = _columns(path)["/events"]
    said = [(t * 1e-9, row[0]) for t, row in zip(events["sim_time"], events["TextLog:text"]) if "goal" in row[0]]
    assert said == [(0.0, "ctbot: goal reached at 0.0 s")]


def test_controller_messages_reach_the_events(tmp_path):
    import logging

    path = tmp_path / "run.rrd"

    def talk(t, readings):
        if abs(t - 0.5) < 1e-9:
            logging.getLogger("my_controller").warning("half a second gone")
        return WheelSpeeds(0.0, 0.0)

    run(load_world("empty"), [RobotSetup(CTBOT, FunctionController(talk))], duration=1.0, observers=[Recorder(path)])
    events = _columns(path)["/events"]
    said = [(t * 1e-9, row[0]) for t, row in zip(events["sim_time"], events["TextLog:text"]) if "half" in row[0]]
    assert said == [(pytest.approx(0.5), "my_controller: half a second gone")]


def test_interrupted_run_is_still_readable(tmp_path, ctrl_c):
    """Ctrl-C inside the loop: the recorder flushes and closes the file."""
    path = tmp_path / "run.rrd"

    def drive(t, readings):
        if t >= 0.5:
            signal.raise_signal(signal.SIGINT)
        return WheelSpeeds(0.1, 0.1)

    result = run(load_world("maze"), [RobotSetup(CTBOT, FunctionController(drive))], duration=5.0, observers=[Recorder(path)])
    assert result.reason == "interrupted"
    body = _columns(path)[f"/world/{result.robots[0].name}/body"]
    assert len(body["Transform3D:translation"]) == len(result.time)


def _closed_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]  # closed again when this returns: nothing listens there


def test_no_viewer_costs_the_live_view_only(tmp_path, capsys):
    from sim.cli.entry import main

    out = tmp_path / "o"
    code = main(["run", "empty", "--controller", "square", "--duration", "2", "--connect", f"rerun+http://127.0.0.1:{_closed_port()}/proxy", "--out", str(out), "--no-report"])
    err = capsys.readouterr().err
    assert code == 0
    assert err.count("\n") == 1 and err.startswith("ctsim: live view off: no rerun viewer answers at ")
    assert len(_columns(out / "run.rrd")["/world/ctbot/body"]["sim_time"]) == 201
    assert (out / "summary.json").is_file() and (out / "truth.tum").is_file()


def test_live_spawns_a_viewer_for_its_stream_and_streams_to_it(tmp_path, monkeypatch, capsys):
    """`--live` without `--connect` starts a viewer on LIVE_PORT and streams the run to it. The
    viewer stands in for itself: rerun's own gRPC server in this process, started where rerun
    would start the viewer's process (never a real viewer in tests), so that the spawn is not
    ignored for want of an active recording and the stream has someone to deliver to."""
    import rerun
    import rerun.sinks

    from sim.views.recording import live

    port = _closed_port()
    spawned: list[int] = []
    standin = rerun.RecordingStream("viewer-standin")

    def spawn_viewer(*, port, **_):
        spawned.append(port)
        standin.serve_grpc(grpc_port=port)

    monkeypatch.setattr(live, "LIVE_PORT", port)
    monkeypatch.setattr(rerun.sinks, "_spawn_viewer", spawn_viewer)
    recorder = Recorder(tmp_path / "run.rrd", live=True)
    result = run(load_world("empty"), [RobotSetup(CTBOT, FunctionController(_drive))], duration=0.5, observers=[recorder])
    assert spawned == [port]
    assert result.reason == "duration" and recorder.live_lost is None
    assert capsys.readouterr().err == ""  # no "live view off"
    standin.disconnect()


class _Viewer:
    """Stands in for a live viewer's stream: notes the entities sent to it, and when."""

    def __init__(self):
        self.sent: list[tuple[str, int]] = []  # (entity, samples sent before it)

    def send_columns(self, path, times, columns):
        self.sent.append((path, len(times[0].times)))

    def log(self, *args, **kwargs): ...
    def set_time(self, *args, **kwargs): ...
    def flush(self, *args, **kwargs): ...
    def disconnect(self): ...


def test_a_live_view_gets_samples_before_a_chunk_fills_and_the_file_keeps_every_one(tmp_path, monkeypatch):
    """A run paced at real time fills a chunk every 80 s: a live view gets what is buffered once
    LIVE_EVERY_S has passed (here 0 s: every sample), and the file, sent the same pieces, still
    holds every pose and an unbroken trail."""
    from sim.views.recording import live

    viewer = _Viewer()

    def open_live(self, rr, blueprint):
        self._live = viewer
        self.streams.append(viewer)

    monkeypatch.setattr(live, "LIVE_EVERY_S", 0.0)
    monkeypatch.setattr(Recorder, "_open_live", open_live)
    path = tmp_path / "run.rrd"
    result = run(load_world("maze"), [RobotSetup(CTBOT, FunctionController(_drive))], duration=0.5, observers=[Recorder(path, live=True)])
    bodies = [count for entity, count in viewer.sent if entity == "world/ctbot/body"]
    assert len(bodies) == len(result.time) == 51 and set(bodies) == {1}  # one sample a send, none held back
    columns = _columns(path)
    truth = result.robots[0].truth_array()
    np.testing.assert_allclose(np.array(columns["/world/ctbot/body"]["Transform3D:translation"])[:, 0, :2], truth[:, :2], atol=1e-6)  # float32
    pieces = columns["/world/ctbot/trail/truth"]["LineStrips2D:strips"]
    joined = np.concatenate([np.array(row[0])[1:] for row in pieces])  # each piece starts at the last one's end
    np.testing.assert_allclose(joined, truth[1:, :2], atol=1e-6)


class _Putter:
    """Puts robot 0 down at PUT_AT (`World.put_robot`, as a click in `ctsim play` does) once its
    run has taken PUT_AFTER samples."""

    def on_sample(self, world, logs):
        if len(logs[0]) == PUT_AFTER:
            world.put_robot(0, PUT_AT)


PUT_AFTER = 37
"""Samples before the put: inside a trail piece, not at its end (TRAIL_EVERY 10)."""
PUT_AT = (1.80, 1.80, np.pi)
"""A free place in the maze, far from where the robot drives."""


@pytest.mark.parametrize("every_sample", [False, True], ids=["one chunk", "a send per sample"])
def test_the_true_trail_breaks_where_the_robot_was_put_down_and_the_estimates_do_not(tmp_path, monkeypatch, every_sample):
    """A robot put down elsewhere mid-run (`World.put_robot`): its true trail is two pieces, none
    of its lines from where it was to where it was put, and every other step drawn; its
    estimates (whose odometry does not see the put) are drawn unbroken. So where the trail is
    sent in one go and where each sample is sent alone (a live view: the put's line would be
    the one from the last send's end)."""
    from sim.views.recording import live

    if every_sample:
        monkeypatch.setattr(live, "LIVE_EVERY_S", 0.0)
        monkeypatch.setattr(Recorder, "_open_live", lambda self, rr, blueprint: (setattr(self, "_live", _Viewer()), self.streams.append(self._live)))
    path = tmp_path / "run.rrd"
    result = run(load_world("maze"), [RobotSetup(CTBOT, FunctionController(_drive))], duration=1.0, observers=[_Putter(), Recorder(path, live=every_sample)])
    log = result.robots[0]
    assert log.puts == [PUT_AFTER]
    truth = log.truth_array()[:, :2]
    assert np.allclose(truth[PUT_AFTER], PUT_AT[:2], atol=0.01) and np.hypot(*(truth[PUT_AFTER] - truth[PUT_AFTER - 1])) > 1.0
    columns = _columns(path)

    def lines(label):
        """The trail's lines (from, to) of points, and its pieces once joined where one ends and the next begins."""
        drawn = [np.array(strip) for row in columns[f"/world/{log.name}/trail/{label}"]["LineStrips2D:strips"] for strip in row if len(strip) > 1]
        segments = np.concatenate([np.stack((strip[:-1], strip[1:]), axis=1) for strip in drawn])
        pieces = 1 + sum(not np.allclose(a[-1], b[0]) for a, b in zip(drawn, drawn[1:]))
        return segments, pieces

    segments, pieces = lines("truth")
    steps = np.stack((truth[:-1], truth[1:]), axis=1)
    np.testing.assert_allclose(segments, np.delete(steps, PUT_AFTER - 1, axis=0), atol=1e-6)
    assert pieces == 2
    for label, poses in log.estimate_arrays().items():
        segments, pieces = lines(label)
        assert pieces == 1 and len(segments) == len(poses) - 1


def test_viewer_that_goes_away_costs_the_live_view_only(tmp_path, capsys):
    """Something accepts the connection, then hangs up on every gRPC call (as a viewer that was
    closed mid-run): the run and its file carry on."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen()
    server.settimeout(30.0)

    def hang_up():
        try:
            while True:
                connection, _ = server.accept()
                connection.close()
        except OSError:
            return

    threading.Thread(target=hang_up, daemon=True).start()
    path = tmp_path / "run.rrd"
    recorder = Recorder(path, connect=f"rerun+http://127.0.0.1:{server.getsockname()[1]}/proxy")
    try:
        result = run(load_world("empty"), [RobotSetup(CTBOT, FunctionController(_drive))], duration=(2 * CHUNK) * 0.01, observers=[recorder])
    finally:
        server.close()
    err = capsys.readouterr().err
    assert result.reason == "duration"
    assert err.count("\n") == 1 and err.startswith("ctsim: live view off: the rerun viewer stopped taking data")
    assert recorder.live_lost and recorder.streams == []
    assert len(_columns(path)["/world/ctbot/body"]["sim_time"]) == len(result.time)


def test_ctsim_run_leaves_pandas_unloaded_and_usable(tmp_path):
    """pyarrow would import pandas (40 MB) on rerun's first string conversion; `ctsim run` keeps it
    out, and pandas loaded afterwards still converts through pyarrow (a Categorical column comes
    back from Parquet as a Categorical). Its own process: this one has pandas loaded already."""
    import subprocess
    import sys

    script = f"""
import sys
from sim.cli.entry import main
code = main(["run", "maze", "--duration", "0.5", "--no-report", "--out", {str(tmp_path / "out")!r}])
assert code == 0, code
assert "pandas" not in sys.modules, "pandas loaded by the recording"
import pandas as pd
frame = pd.DataFrame({{"kind": pd.Categorical(["a", "b"]), "x": [1.0, 2.0]}})
frame.to_parquet({str(tmp_path / "t.parquet")!r})
back = pd.read_parquet({str(tmp_path / "t.parquet")!r})
assert isinstance(back["kind"].dtype, pd.CategoricalDtype) and back["x"].tolist() == [1.0, 2.0], back.dtypes
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_a_library_recording_reads_back_with_timestamps_in_the_same_process(tmp_path):
    """A recording made through the Python API leaves pyarrow as it was: reading the file back in
    the same process turns its nanosecond log times into Python objects (pyarrow needs pandas for
    that; `keep_pandas_out_of_arrow` is for the CLI only). Its own process, which starts without
    pandas, as a user's script does."""
    import subprocess
    import sys

    script = f"""
import rerun
from bots.commands import WheelSpeeds
from bots.controller import FunctionController
from bots.ctbot import CTBOT
from sim.run.loop import RobotSetup, run
from sim.views.recording.recorder import Recorder
from sim.world.files import load_world
path = {str(tmp_path / "run.rrd")!r}
run(load_world("maze"), [RobotSetup(CTBOT, FunctionController(lambda t, r: WheelSpeeds(0.1, 0.1)))], 0.5, observers=[Recorder(path)])
rows = [row for chunk in rerun.chunk.RrdReader(path).stream().to_chunks() for row in chunk.to_record_batch().to_pylist()]
assert any("log_time" in row for row in rows), rows[:1]
"""
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
