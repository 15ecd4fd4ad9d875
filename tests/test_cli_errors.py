"""User mistakes told from ctsim's bugs: a `sim.errors.UserError` (or an OSError on a path the
command line named) is one line and exit 2; anything else raised inside ctsim is a bug, shown
with its traceback and a request to report it, exit 1."""

from __future__ import annotations

import pytest

from bots.controller import ControllerError
from bots.ir_curve import CurveFileError
from bots.noise import RobotSettingError
from bots.schema import FileError
from sim.cli import options as cli
from sim.cli.entry import main
from sim.contest.entries import EntryError
from sim.contest.store import StoreError
from sim.errors import UserError
from sim.experiments.plan import SpecError
from sim.experiments.report import ReportError
from sim.lab.exercise import ExerciseError
from sim.run.ending import RunError
from sim.web.serve import ViewError
from sim.world import World
from sim.world.chassis_drive import FaultError
from sim.world.spec import WorldFileError

RUN = ["run", "--controller", "drive_distance", "--duration", "0.2", "--no-report"]


@pytest.mark.parametrize("error", [FileError, WorldFileError, CurveFileError, RobotSettingError, ControllerError, RunError, FaultError,
                                   SpecError, ReportError, ExerciseError, EntryError, StoreError, ViewError, cli.UsageError])
def test_every_loader_error_is_a_user_error(error):
    assert issubclass(error, UserError)


def _break_the_world(monkeypatch, exception: BaseException) -> None:
    def step(self, commands):  # noqa: ANN001, ANN202 (World.step's signature)
        raise exception

    monkeypatch.setattr(World, "step", step)


@pytest.mark.parametrize("bug", [IndexError("index 3 is out of bounds for axis 0 with size 2"),
                                 ValueError("operands could not be broadcast together with shapes (2,) (3,)")])
def test_a_bug_in_the_world_step_shows_its_traceback_and_exits_1(tmp_path, monkeypatch, capsys, bug):
    """A ValueError from inside the world is no user mistake (it was once reported as one)."""
    _break_the_world(monkeypatch, bug)
    assert main([*RUN, "--out", str(tmp_path / "o")]) == cli.EXIT_FAILED
    err = capsys.readouterr().err
    assert "Traceback (most recent call last)" in err and f"{type(bug).__name__}: {bug}" in err
    assert err.strip().splitlines()[-1].startswith("ctsim: error: this is a bug in ctsim")


def test_an_os_error_on_a_path_the_user_named_is_one_line(tmp_path, monkeypatch, capsys):
    out = tmp_path / "o"
    _break_the_world(monkeypatch, PermissionError(13, "Permission denied", str(out / "inside" / "file")))
    assert main([*RUN, "--out", str(out)]) == cli.EXIT_USER
    err = capsys.readouterr().err
    assert err == f"ctsim: error: {out / 'inside' / 'file'}: Permission denied\n"


def test_an_os_error_elsewhere_is_a_bug(tmp_path, monkeypatch, capsys):
    _break_the_world(monkeypatch, FileNotFoundError(2, "No such file or directory", str(tmp_path / "not-named" / "cache.bin")))
    assert main([*RUN, "--out", str(tmp_path / "o")]) == cli.EXIT_FAILED
    assert "Traceback" in capsys.readouterr().err


def test_a_run_folder_that_cannot_be_made_is_the_users(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    assert main([*RUN, "--out", str(tmp_path / "file" / "o")]) == cli.EXIT_USER
    err = capsys.readouterr().err
    assert err.startswith(f"ctsim: error: {tmp_path / 'file' / 'o'}: cannot make the run's folder") and "Traceback" not in err


def test_a_controller_that_cannot_drive_the_robot_is_refused_before_the_run(tmp_path, capsys):
    """solve_maze needs IR sensors; a robot without them is the user's choice, named by robot."""
    assert main(["run", "--robot", "omni3", "--controller", "solve_maze", "--duration", "0.2", "--out", str(tmp_path / "o")]) == cli.EXIT_USER
    err = capsys.readouterr().err
    assert err.startswith("ctsim: error: ") and len(err.strip().splitlines()) == 1


@pytest.mark.parametrize(("settings", "said"), [
    (["ir.min_range=0.7", "ir.max_range=0.2"], "ir.max_range: min_range must be less than max_range (0.2 m), not 0.7"),
    (["ir.min_range=0.9"], "ir.min_range: must be less than max_range (0.8 m), not 0.9"),
])  # fmt: skip
def test_a_robot_setting_that_breaks_another_fields_check_names_both(tmp_path, capsys, settings, said):
    """A --robot-set that makes another field's check fail (max_range below the min_range) names
    the setting and the field that failed (it said 'ir.max_range: must be less than max_range')."""
    arguments = [part for setting in settings for part in ("--robot-set", setting)]
    assert main(["run", *arguments, "--duration", "1", "--no-report", "--out", str(tmp_path / "o")]) == 2
    assert said in capsys.readouterr().err
