"""One writer per output folder: while one ctsim command writes a folder (here held by
`sim.folder_lock.hold`, as any command holds it), a second run, sweep, contest or lab grading
into it is refused at once in one line naming the holder, and nothing of the second is written."""

from __future__ import annotations

import os

import pytest

import sim.folder_lock
from sim.cli.entry import main
from sim.experiments import sweep
from sim.folder_lock import LOCK, FolderInUse, hold, holder

fcntl = pytest.importorskip("fcntl", reason="folders are locked on POSIX only")

SPEC = '[base]\nworld = "empty"\ncontroller = "idle"\nduration = 0.05\n[axes]\nseed = [0, 1]\n'


def status(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as done:
        return done.code


@pytest.fixture()
def taken(tmp_path):
    """A folder another ctsim command (a run) is writing."""
    folder = tmp_path / "out"
    handle = hold(folder, "run")
    yield folder
    handle.close()


def refused_in_one_line(capsys, folder) -> None:
    err = capsys.readouterr().err
    assert err == f"ctsim: error: {folder} is in use by another ctsim run (process {os.getpid()}); wait for it to end or give another --out\n"
    assert sorted(p.name for p in folder.iterdir()) == [LOCK]  # nothing of the second command
    assert holder(folder) == f"process {os.getpid()}, ctsim run"  # the first's lock file kept, and held


def test_a_second_run_into_a_folder_is_refused(taken, capsys):
    assert status(["run", "empty", "--controller", "idle", "--duration", "0.05", "--no-report", "--out", str(taken)]) == 2
    refused_in_one_line(capsys, taken)


def test_a_second_sweep_into_a_folder_is_refused(taken, tmp_path, capsys):
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    assert status(["sweep", str(spec), "--out", str(taken), "--engine", "serial"]) == 2
    refused_in_one_line(capsys, taken)


def test_the_sweep_api_holds_its_folder_too(taken):
    with pytest.raises(FolderInUse, match="in use by another ctsim run"):
        sweep({"base": {"world": "empty", "controller": "idle", "duration": 0.05}, "axes": {"seed": [0]}}, taken, progress=False)


def test_a_second_contest_into_a_folder_is_refused(taken, capsys):
    assert status(["contest", "contest", "solve_maze", "idle", "--out", str(taken), "--engine", "serial"]) == 2
    refused_in_one_line(capsys, taken)


def test_a_second_lab_grading_into_a_folder_is_refused(taken, tmp_path, capsys):
    submissions = tmp_path / "submissions"
    submissions.mkdir()
    (submissions / "alice.py").write_text("def icc(*args):\n    return 0.0\n")
    assert status(["lab", "grade", "1", str(submissions), "--out", str(taken), "--degraded"]) == 2
    refused_in_one_line(capsys, taken)


def test_a_folder_is_free_again_once_its_holder_ends(tmp_path):
    first = hold(tmp_path / "out", "sweep")
    with pytest.raises(FolderInUse, match=f"in use by another ctsim sweep \\(process {os.getpid()}\\)"):
        hold(tmp_path / "out", "contest")
    first.close()
    assert not (tmp_path / "out" / LOCK).exists()  # removed as its holder ended
    hold(tmp_path / "out", "contest").close()


def test_a_command_that_ends_leaves_no_lock_file(tmp_path):
    """A finished folder holds what the command wrote, not its lock."""
    run = tmp_path / "run"
    assert status(["run", "empty", "--controller", "idle", "--duration", "0.05", "--no-report", "--out", str(run)]) == 0
    spec = tmp_path / "spec.toml"
    spec.write_text(SPEC)
    assert status(["sweep", str(spec), "--out", str(tmp_path / "sweep"), "--engine", "serial"]) == 0
    sweep({"base": {"world": "empty", "controller": "idle", "duration": 0.05}, "axes": {"seed": [0]}}, tmp_path / "api", progress=False)
    submissions = tmp_path / "submissions"
    submissions.mkdir()
    (submissions / "alice.py").write_text("def turn(*args):\n    return 0.0, 0.0, 0.0, 0.0\n")
    status(["lab", "grade", "1", str(submissions), "--out", str(tmp_path / "grades"), "--degraded"])
    for folder in (run, tmp_path / "sweep", tmp_path / "api", tmp_path / "grades"):
        assert folder.is_dir() and not (folder / LOCK).exists(), folder


def test_a_lock_file_put_in_the_place_of_the_held_one_is_left_alone(tmp_path):
    """Someone removed the held lock file and made another (by hand: no ctsim command does):
    ending the command removes only the file it held."""
    held = hold(tmp_path, "run")
    (tmp_path / LOCK).unlink()
    (tmp_path / LOCK).write_text("4242 sweep\n")
    held.close()
    assert (tmp_path / LOCK).read_text() == "4242 sweep\n"


def test_a_holder_ending_between_another_s_open_and_lock_leaves_one_holder(tmp_path, monkeypatch):
    """The second command opened the lock file just before the first removed it and let go: the
    lock it then gets is of a removed file, so it takes a new lock file; a third is refused."""
    first = hold(tmp_path, "run")
    opened = sim.folder_lock._open

    def open_then_first_ends(path, flags):
        handle = opened(path, flags)
        if not first.handle.closed:
            first.close()
        return handle

    monkeypatch.setattr(sim.folder_lock, "_open", open_then_first_ends)
    second = hold(tmp_path, "sweep")
    monkeypatch.setattr(sim.folder_lock, "_open", opened)
    try:
        assert (tmp_path / LOCK).read_text() == f"{os.getpid()} sweep\n"
        with pytest.raises(FolderInUse, match="another ctsim sweep"):
            hold(tmp_path, "contest")
    finally:
        second.close()
