"""Runs a user can trust: honest defaults, one meaning per exit status, bad input of any kind
answered in one line, bounded memory (issue 17)."""

from __future__ import annotations

import json
import math
import tempfile
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bots.commands import Twist
from bots.controller import FunctionController
from bots.ctbot import CTBOT
from bots.noise import NOISE_PRESETS, RobotSettingError, with_noise, with_settings
from sim.cli.entry import main
from sim.cli.options import EXIT_FAILED, EXIT_USER
from sim.run.loop import RobotSetup, run
from sim.world.files import load_world, worlds_dir

STATUSES = {0, EXIT_FAILED, EXIT_USER}


def test_help_lists_every_exit_status(capsys):
    for argv in (["--help"], ["run", "--help"], ["check", "--help"]):
        with pytest.raises(SystemExit):
            main(argv)
        text = capsys.readouterr().out
        for status in ("0 ", "1 ", "2 ", "130", "143"):
            assert f"\n  {status}" in text, (argv, status)


def _end_pose(tmp_path: Path, *args: str) -> tuple[np.ndarray, dict]:
    out = tmp_path / "-".join(args).replace("/", "_")
    assert main(["run", "empty", "--controller", "drive_distance", "--duration", "2", "--no-report", "--out", str(out), *args]) == 0
    summary = json.loads((out / "summary.json").read_text())
    return np.loadtxt(out / "truth.tum")[-1, 1:3], summary  # random slip moves the true robot


def test_seed_matters_with_noise_and_not_without(tmp_path):
    a, summary = _end_pose(tmp_path, "--seed", "1", "--noise", "realistic")
    b, _ = _end_pose(tmp_path, "--seed", "2", "--noise", "realistic")
    again, _ = _end_pose(tmp_path, "--noise", "realistic", "--seed", "1")
    assert summary["noise"] == "realistic"
    assert not np.array_equal(a, b) and np.array_equal(a, again)  # seeded, reproducible
    default, summary = _end_pose(tmp_path, "--seed", "1")
    assert summary["noise"] == "realistic" and np.array_equal(default, a)  # the default: realistic noise
    c, quiet = _end_pose(tmp_path, "--seed", "1", "--noise", "none")
    d, _ = _end_pose(tmp_path, "--seed", "2", "--noise", "none")
    assert quiet["noise"] == "none" and np.array_equal(c, d)  # exact sensors: the seed changes nothing


def test_presets_and_overrides():
    realistic = with_noise(CTBOT, "realistic")
    assert realistic.mouse.scale_error == pytest.approx(415 / 400 - 1)  # the real bot's 415 cpi
    assert all(s.noise_std > 0 for s in realistic.ir + realistic.line + realistic.border + realistic.light)
    assert with_noise(CTBOT, "none") == CTBOT
    assert set(NOISE_PRESETS) == {"none", "realistic", "harsh"}
    changed = with_settings(CTBOT, {"encoders.slip_std": 0.02, "ir.noise_std": 0.01, "encoders.diameter_error": [0, 0.01]})
    assert changed.encoders.slip_std == 0.02 and {s.noise_std for s in changed.ir} == {0.01}
    assert changed.encoders.diameter_error == (0, 0.01)
    for key, value, words in (
        ("encoders.slip", 0.02, "did you mean 'slip_std'"),
        ("encoders.slip_std", "lots", "must be a number"),
        ("encoders.slip_std", -1, "at least 0 and at most 1, not -1"),
        ("encoders.diameter_error", 0.1, "a list of 2 numbers"),
        ("engine.power", 1, "no section 'engine'"),
    ):
        with pytest.raises(RobotSettingError, match=words):
            with_settings(CTBOT, {key: value})


def test_summary_is_strict_json_with_typed_parameters(tmp_path):
    out = tmp_path / "s"
    assert main(["run", "empty", "--controller", "drive_distance", "--param", "distance_m=0.3", "--duration", "0.5",
                 "--no-report", "--out", str(out), "--robot-set", "encoders.slip_std=0.02"]) == 0
    text = (out / "summary.json").read_text()
    summary = json.loads(text, parse_constant=lambda name: pytest.fail(f"non-standard JSON constant {name}"))
    assert summary["robots"][0]["params"] == {"distance_m": 0.3}
    assert summary["robot_set"] == {"encoders.slip_std": 0.02}
    assert summary["robots"][0]["estimates"]["encoders"]["rpe_translation"] is None  # nan: shorter than 2 m


def test_a_reused_output_folder_keeps_nothing_stale(tmp_path):
    out = tmp_path / "again"
    assert main(["run", "maze", "--controller", "idle", "--robots", "2", "--duration", "0.2", "--out", str(out)]) == 0
    assert len(list(out.glob("*_truth.tum"))) == 2
    (out / "notes.txt").write_text("mine")
    assert main(["run", "empty", "--controller", "idle", "--duration", "0.2", "--out", str(out), "--no-report"]) == 0
    assert not list(out.glob("*_truth.tum")) and not list(out.glob("*.png"))
    assert (out / "truth.tum").is_file() and (out / "notes.txt").read_text() == "mine"  # only ctsim's own files go


def test_run_warns_of_a_start_inside_a_wall(tmp_path, capsys):
    world = tmp_path / "w.toml"
    world.write_text('name = "w"\nbounds = [0, 0, 2, 2]\n[[wall]]\nbox = [0.5, 0.5, 1.5, 1.5]\n[[start]]\nposition = [1.0, 1.0]\n')
    assert main(["run", str(world), "--controller", "idle", "--duration", "0.1", "--no-report", "--out", str(tmp_path / "o")]) == 0
    err = capsys.readouterr().err
    assert err.startswith(f"ctsim: warning: {world}: start #1") and "inside a wall" in err


def test_play_without_a_display_refuses_instead_of_running_unseen(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setenv("SDL_VIDEODRIVER", "dummy")
    assert main(["play", "maze"]) == EXIT_USER
    assert "needs a display" in capsys.readouterr().err


def test_controllers_lists_whole_sentences(capsys):
    assert main(["controllers"]) == 0
    descriptions: list[str] = []
    for line in capsys.readouterr().out.splitlines():
        if not line.startswith(" "):
            descriptions.append(line)
        elif not line.strip().startswith("parameters:"):
            descriptions[-1] += " " + line.strip()
    assert len(descriptions) > 5
    for description in descriptions:
        assert description.endswith((".", ")")), description  # a whole first paragraph, not its first line


# --- fuzz: random arguments and random world files -------------------------------------------

OPTIONS = {
    "--controller": ["idle", "drive_distance", "nonsense", "x.py", "square"],
    "--param": ["distance_m=0.1", "distance_m=abc", "=", "nope=1", "laps=2"],
    "--duration": ["0.05", "0", "-1", "nan", "inf", "abc"],
    "--dt": ["0.01", "0.05", "0", "-0.01", "x"],
    "--seed": ["0", "7", "-1", "1.5", "x"],
    "--robots": ["1", "2", "0", "-3", "x"],
    "--noise": ["none", "realistic", "harsh", "loud"],
    "--robot-set": ["encoders.slip_std=0.1", "mouse.dpi=415", "ir.noise_std=-1", "a.b=c", "track_width=0", "x"],
    "--robot": ["ctbot", "nobot", "missing.toml"],
    "--until-goal": [],
    "--no-until-goal": [],
}


def _mutated_world(draw) -> str:
    lines = (worlds_dir() / draw(st.sampled_from(["maze.toml", "line.toml", "square.toml", "holes_lights.toml"]))).read_text().splitlines()
    for _ in range(draw(st.integers(0, 4))):
        if not lines:
            break
        i = draw(st.integers(0, len(lines) - 1))
        action = draw(st.sampled_from(["drop", "dup", "garble", "number"]))
        if action == "drop":
            del lines[i]
        elif action == "dup":
            lines.insert(i, lines[i])
        elif action == "garble":
            lines[i] = lines[i][: draw(st.integers(0, len(lines[i])))] + draw(st.text("[]{}=\"',.#0123456789abc \t", max_size=8))
        else:
            lines[i] = "".join(draw(st.sampled_from(["-1", "1e9", "nan", "0", "[]"])) if c.isdigit() else c for c in lines[i])
    return "\n".join(lines) + "\n"


@st.composite
def command_lines(draw) -> tuple[list[str], str | None]:
    world = draw(st.one_of(st.none(), st.just("shipped"), st.just("missing")))
    text = _mutated_world(draw) if world is None else None
    argv = ["run", {"shipped": "empty", "missing": "no_such_world", None: "WORLD"}[world]]
    for option in draw(st.lists(st.sampled_from(sorted(OPTIONS)), max_size=5)):
        argv.append(option)
        if OPTIONS[option]:
            argv.append(draw(st.sampled_from(OPTIONS[option])))
    argv += ["--duration", draw(st.sampled_from(["0.05", "0.1", "-1"]))]  # last one wins: runs stay short
    command = draw(st.sampled_from(["run", "run", "run", "check"]))
    if command == "check":
        argv = ["check", argv[1]]
    return argv, text


@settings(max_examples=40, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(command_lines())
def test_fuzzed_command_lines_end_in_a_documented_status_and_one_line(capsys, case):
    argv, world_text = case
    with tempfile.TemporaryDirectory() as folder:
        if world_text is not None:
            (Path(folder) / "world.toml").write_text(world_text)
            argv = [str(Path(folder) / "world.toml") if a == "WORLD" else a for a in argv]
        argv += ["--out", str(Path(folder) / "out"), "--no-report"] if argv[0] == "run" else []
        try:
            status = main(argv)
        except SystemExit as exit_:  # argparse's own refusals
            status = exit_.code
    captured = capsys.readouterr()
    assert status in STATUSES, (argv, status, captured.err)
    assert "Traceback" not in captured.err
    errors = [line for line in captured.err.splitlines() if line and not line.startswith("ctsim: warning:")]
    if status == 0:
        assert not errors, (argv, captured.err)
    else:
        assert len(errors) == 1 and errors[0].startswith("ctsim: "), (argv, captured.err)


# --- memory -------------------------------------------------------------------------------------


class _MemoryPerMinute:
    def __init__(self):
        self.samples: list[tuple[float, int]] = []

    def on_sample(self, world, logs) -> None:  # noqa: ANN001
        if world.time % 60.0 < world.dt / 2:
            self.samples.append((world.time, tracemalloc.get_traced_memory()[0]))


def test_memory_per_simulated_minute_does_not_grow():
    """10 simulated minutes of a c't-Bot with every sensor and the four estimators: after the first
    minute (caches, compiled kernels) the Python heap must stay flat. Keeping each step's readings
    as objects cost ~4 KB a step, 24 MB a minute; the bound, 100 KB a minute, is 0.4 % of that
    and far above what allocator noise does."""
    drive = FunctionController(lambda t, r: Twist(0.1, 0.3 * math.sin(t / 10)))
    probe = _MemoryPerMinute()
    tracemalloc.start()
    try:
        run(load_world("empty"), [RobotSetup(CTBOT, drive)], 600.0, observers=[probe])
    finally:
        tracemalloc.stop()
    times, used = np.array(probe.samples).T
    assert len(times) == 11
    per_minute = np.diff(used[1:])
    assert per_minute.max() < 100_000, per_minute
