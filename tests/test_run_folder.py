"""What a run writes stays its own and inside its folder: readings a controller gets cannot
rewrite the recorded sensor data, robot names become file names inside the folder (or are
refused when nothing of them is left), and a run of many robots writes every trajectory file
with few handles open at once."""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bots.commands import Twist
from bots.schema import Problem, file_stem
from bots.spec import RobotSpec
from sim.analysis.export import MOST_OPEN, write_run
from sim.experiments import Bot, simulate

resource = pytest.importorskip("resource", reason="file handle limits are POSIX")


class Writes:
    """Writes into its readings, as a controller that smooths them in place would."""

    def step(self, t, readings):
        readings.ir_distance[:] = 0.123
        return Twist(0.1, 0.0)


class Reads:
    """Keeps what it saw."""

    def __init__(self):
        self.seen = []

    def step(self, t, readings):
        self.seen.append(readings.ir_distance.copy())
        return Twist(0.1, 0.0)


def test_a_controller_cannot_write_into_its_readings():
    result = simulate("maze", Bot(Writes()), duration=0.05)
    assert result.reason == "error" and "assignment destination is read-only at step 0" in result.error


def test_the_readings_a_controller_saw_are_the_recorded_ones():
    reader = Reads()
    result = simulate("maze", Bot(reader), duration=0.05)
    recorded = result.raw.robots[0].readings(slice(0, len(reader.seen)))["ir_distance"]
    np.testing.assert_array_equal(np.array(reader.seen), recorded)


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=40))
def test_a_robot_name_becomes_a_plain_file_name_or_is_refused(name):
    stem = file_stem(name)
    assert "/" not in stem and "\\" not in stem and "\0" not in stem and not stem.startswith(".")
    assert stem == "" or stem.strip(".") != ""
    if stem:
        assert RobotSpec(name=name, wheel_diameter=0.05, track_width=0.09, body_radius=0.06).name == name
    else:
        with pytest.raises(Problem, match="leaves nothing to name the robot's files by"):
            RobotSpec(name=name, wheel_diameter=0.05, track_width=0.09, body_radius=0.06)


@pytest.mark.parametrize("name", ["../../../x", "/abs/path", "a/../../b", "..hidden"])
def test_files_of_a_robot_with_a_path_for_a_name_stay_in_the_folder(tmp_path, name):
    result = simulate("empty", Bot("square", changes={"name": name}), duration=0.05)
    out = tmp_path / "deep" / "out"
    written = write_run(result.raw, out, with_csv=True)
    paths = [path for tracks in written.values() for path in tracks.values()]
    assert paths and all(path.parent == out and not path.name.startswith(".") for path in paths)
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) == sorted(p.name for p in out.iterdir())


def test_robots_whose_names_come_out_alike_get_files_of_their_own(tmp_path):
    result = simulate("empty", Bot("idle", changes={"name": "a b"}), Bot("idle", changes={"name": "a_b"}), duration=0.05)
    written = write_run(result.raw, tmp_path, with_csv=True)
    assert len({path for tracks in written.values() for path in tracks.values()}) == sum(len(t) for t in written.values())


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="counts open handles in /proc")
def test_many_robots_are_written_with_few_handles_open(tmp_path):
    """30 robots, 5 tracks each, TUM and CSV: 300 files under a limit of MOST_OPEN + 40 handles."""
    world = tmp_path / "wide.toml"
    world.write_text("bounds = [0, 0, 10, 4]\n" + "".join(f"[[start]]\nposition = [{0.3 + 0.3 * k:.1f}, 2]\nslot = {k + 1}\n" for k in range(30)))
    result = simulate(str(world), robots=[Bot("idle")] * 30, duration=0.05)
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (len(os.listdir("/proc/self/fd")) + MOST_OPEN + 40, hard))
    try:
        written = write_run(result.raw, tmp_path / "out", with_csv=True)
    finally:
        resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))
    files = sorted((tmp_path / "out").iterdir())
    assert len(files) == 2 * sum(len(t) for t in written.values()) >= 300
    assert all(path.read_text().count("\n") == 1 + len(result.raw) for path in files if path.suffix == ".tum")


def status(argv: list[str]) -> int:
    from sim.cli.entry import main

    try:
        return main(argv)
    except SystemExit as done:
        return done.code


RUN = ["run", "empty", "--controller", "square", "--duration", "0.05", "--no-report"]


def test_a_folder_of_other_files_is_refused_and_left_alone(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "data.csv").write_text("mine\n")
    (out / "plot.png").write_bytes(b"png")
    assert status([*RUN, "--out", str(out)]) == 2
    assert "holds files that no ctsim run wrote (data.csv, plot.png)" in capsys.readouterr().err
    assert sorted(p.name for p in out.iterdir()) == ["data.csv", "plot.png"]


@pytest.mark.parametrize("text", ['{"x": 1}', "[]", "not json", '{"reason": "done"}'])
def test_a_folder_with_a_summary_json_no_run_wrote_is_refused_and_left_alone(tmp_path, capsys, text):
    """Someone else's summary.json beside their data once made the folder look like a run's and was overwritten."""
    out = tmp_path / "mine"
    out.mkdir()
    (out / "summary.json").write_text(text)
    (out / "data.csv").write_text("mine\n")
    assert status([*RUN, "--out", str(out)]) == 2
    assert "holds files that no ctsim run wrote (data.csv, summary.json)" in capsys.readouterr().err
    assert (out / "summary.json").read_text() == text and (out / "data.csv").read_text() == "mine\n"


def test_a_reused_run_folder_loses_only_what_the_earlier_run_wrote(tmp_path):
    out = tmp_path / "run"
    assert status([*RUN, "--robots", "2", "--out", str(out)]) == 0
    (out / "notes.csv").write_text("the user's own\n")
    assert status([*RUN, "--out", str(out)]) == 0
    names = {p.name for p in out.iterdir()}
    assert "notes.csv" in names and "truth.tum" in names and not any(n.startswith("ctbot1_") for n in names)


def test_a_controller_that_changes_folder_as_it_loads_cannot_move_the_run(tmp_path, monkeypatch):
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    controller = tmp_path / "moves.py"
    controller.write_text(f"import os\nos.chdir({str(elsewhere)!r})\nfrom bots.commands import Twist\n"
                          "class Moves:\n    def step(self, t, readings):\n        return Twist(0.1, 0.0)\n")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr("sim.cli.output.START", tmp_path)
    assert status(["run", "empty", "--controller", f"{controller}:Moves", "--duration", "0.05", "--no-report", "--out", "out"]) == 0
    assert (tmp_path / "out" / "summary.json").is_file() and not any(elsewhere.iterdir())


def test_a_long_runs_figures_read_a_bounded_number_of_evenly_spread_samples(tmp_path, monkeypatch):
    """A figure draws at most FIGURE_POINTS samples of each trajectory and band, read a line or a
    row group at a time: every k-th and the last, the same samples from the TUM files and from
    run.parquet, and `ctsim report` draws a long run's figures from them."""
    from sim.analysis.run_folder import trajectory_text
    from sim.cli.entry import main
    from sim.views import figures

    out = tmp_path / "run"
    assert main(["run", "empty", "--controller", "wander", "--duration", "3", "--no-report", "--out", str(out)]) == 0  # 301 samples
    monkeypatch.setattr(figures, "FIGURE_POINTS", 40)
    lines = trajectory_text(out, "truth.tum", 40).splitlines()
    every = (301 + 1 + 39) // 40  # (the header line counts as one)
    whole = (out / "truth.tum").read_text().splitlines()
    assert lines == [*whole[::every], whole[-1]] and len(lines) <= 40 + 1
    import pyarrow.parquet as pq

    rows = figures._every_row(pq.ParquetFile(out / "run.parquet"), ["time"]).column("time").to_numpy()
    times = pq.read_table(out / "run.parquet", columns=["time"]).column("time").to_numpy()
    expected = np.append(times[:: -(-301 // 40)], times[-1])
    np.testing.assert_array_equal(rows, expected)
    assert main(["report", str(out)]) == 0 and all(path.stat().st_size > 0 for path in (out / "trajectories.png", out / "errors.png"))


class _Putter:
    """Puts robot 0 down at (1.8, 1.8) facing -x (`World.put_robot`, as a click in `ctsim play`
    does) once its run has taken 37 samples."""

    def on_sample(self, world, logs):
        if len(logs[0]) == 37:
            world.put_robot(0, (1.80, 1.80, np.pi))


def test_the_figures_break_the_truth_where_a_hand_put_the_robot_down(tmp_path, monkeypatch):
    """A robot put down elsewhere mid-run: summary.json gives the time of its first sample there,
    and trajectories.png draws its truth in two pieces (no line from where it was to where it was
    put), its estimates whole (their odometry did not see it)."""
    import json

    from bots.ctbot import CTBOT
    from sim.cli.output import finish
    from sim.run.loop import RobotSetup, run
    from sim.views import figures
    from sim.world.files import load_world

    result = run(load_world("maze"), [RobotSetup(CTBOT, Reads())], duration=1.0, observers=[_Putter()])
    saved = []
    save = figures._save
    monkeypatch.setattr(figures, "_save", lambda fig, path: (saved.append(fig), save(fig, path))[1])
    finish(result, tmp_path, {"duration": 1.0})
    (robot,) = json.loads((tmp_path / "summary.json").read_text())["robots"]
    assert robot["puts"] == [pytest.approx(0.37)]
    lines = {line.get_label(): line.get_xydata() for line in saved[0].axes[0].lines}
    gaps = np.flatnonzero(np.isnan(lines["truth"][:, 0]))
    assert gaps.tolist() == [37]  # (a NaN breaks matplotlib's line: before the 38th sample, the first put down)
    np.testing.assert_allclose(np.delete(lines["truth"], 37, axis=0), result.robots[0].truth_array()[:, :2])
    estimates = [xy for label, xy in lines.items() if label.split(" ")[0] in result.robots[0].estimate_names]
    assert estimates and not any(np.isnan(xy).any() for xy in estimates)
