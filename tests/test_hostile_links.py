"""Links, pipes and devices planted in a folder ctsim writes: the lock, a run's files, a report's
figures and page. Nothing is written through them onto a file outside the folder, nothing blocks
on a pipe, and a lock that is not a regular file of its own is refused in one line (exit 2)."""

from __future__ import annotations

import os
import shutil
import stat

import pytest

from sim.analysis.summary import write_json
from sim.cli.entry import main
from sim.folder_lock import LOCK, hold
from sim.out_files import NotAFileOfItsOwn, subfolder, write_text

pytest.importorskip("fcntl", reason="folders are locked on POSIX only")

PLANTS = ("symlink", "hardlink", "fifo", "folder")
"""What an attacker can put at a name ctsim writes (a device needs root; a FIFO stands for it:
both are files that are not regular)."""


def plant(kind: str, at, victim) -> None:
    """`kind` at path `at`, pointing at (or sharing) the file `victim` where it can."""
    if kind == "symlink":
        os.symlink(victim, at)
    elif kind == "hardlink":
        os.link(victim, at)
    elif kind == "fifo":
        os.mkfifo(at)
    else:
        os.mkdir(at)


@pytest.fixture()
def victim(tmp_path):
    path = tmp_path / "precious.txt"
    path.write_text("the user's own data\n")
    return path


def untouched(victim) -> bool:
    return victim.read_text() == "the user's own data\n"


@pytest.mark.parametrize("kind", PLANTS)
def test_a_lock_that_is_not_a_file_of_its_own_is_refused_in_one_line(kind, tmp_path, victim):
    folder = tmp_path / "out"
    folder.mkdir()
    plant(kind, folder / LOCK, victim)
    with pytest.raises(NotAFileOfItsOwn, match=r"\.ctsim\.lock is a") as refused:
        hold(folder, "run")
    assert "\n" not in str(refused.value)
    assert untouched(victim)


def test_a_run_into_a_folder_whose_lock_is_a_link_is_refused_and_writes_nothing(tmp_path, victim, capsys):
    folder = tmp_path / "out"
    folder.mkdir()
    os.symlink(victim, folder / LOCK)
    assert main(["run", "empty", "--controller", "idle", "--duration", "0.05", "--no-report", "--out", str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ctsim: error: ") and err.count("\n") == 1 and "symbolic link" in err
    assert untouched(victim) and sorted(p.name for p in folder.iterdir()) == [LOCK]


def test_who_holds_a_folder_is_not_read_through_a_pipe(tmp_path):
    from sim.folder_lock import holder

    os.mkfifo(tmp_path / LOCK)
    assert holder(tmp_path) is None  # (at once: a pipe opened without blocking, then refused)


@pytest.mark.parametrize("kind", ("symlink", "hardlink", "fifo"))
def test_summary_json_is_never_written_through_what_stands_at_its_name(kind, tmp_path, victim):
    plant(kind, tmp_path / "summary.json", victim)
    write_json(tmp_path / "summary.json", {"reason": "running"}, reserve=4096)
    assert untouched(victim)
    info = os.lstat(tmp_path / "summary.json")
    assert stat.S_ISREG(info.st_mode) and info.st_nlink == 1
    assert '"running"' in (tmp_path / "summary.json").read_text()


def test_a_file_cannot_replace_a_folder_and_says_so_in_one_line(tmp_path):
    (tmp_path / "report.html").mkdir()
    with pytest.raises(NotAFileOfItsOwn, match="report.html is a folder"):
        write_text(tmp_path / "report.html", "page")
    assert not [p for p in tmp_path.iterdir() if p.name != "report.html"]  # (no temporary left behind)


def test_a_subfolder_that_is_a_link_is_refused(tmp_path):
    outside = tmp_path / "elsewhere"
    outside.mkdir()
    os.symlink(outside, tmp_path / "gradescope")
    with pytest.raises(NotAFileOfItsOwn, match="gradescope is a symbolic link, not a folder of its own"):
        subfolder(tmp_path / "gradescope")
    assert subfolder(tmp_path / "new" / "deeper").is_dir()


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A real run's folder, written once."""
    out = tmp_path_factory.mktemp("run") / "out"
    assert main(["run", "empty", "--controller", "square", "--duration", "0.2", "--no-report", "--out", str(out)]) == 0
    return out


@pytest.mark.parametrize("kind", ("symlink", "hardlink"))
def test_report_writes_its_figures_and_page_beside_links_never_through_them(kind, run, tmp_path, victim, capsys):
    folder = tmp_path / "copy"
    shutil.copytree(run, folder, ignore=shutil.ignore_patterns(LOCK))
    victims = {}
    for name in ("trajectories.png", "errors.png", "report.html"):
        victims[name] = tmp_path / f"victim-{name}"
        shutil.copy(victim, victims[name])
        (folder / name).unlink(missing_ok=True)
        plant(kind, folder / name, victims[name])
    os.symlink(victim, folder / "secret.png")  # (a page must not carry a file from outside away)
    assert main(["report", str(folder)]) == 0
    assert all(untouched(v) for v in victims.values())
    assert all(os.lstat(folder / name).st_nlink == 1 and not (folder / name).is_symlink() for name in victims)
    assert "the user" not in (folder / "report.html").read_text()
    capsys.readouterr()


@pytest.mark.parametrize("kind", ("symlink", "hardlink", "fifo"))
def test_a_contest_database_is_never_opened_through_what_stands_at_its_name(kind, tmp_path, victim):
    from sim.contest.store import FILE, Store

    plant(kind, tmp_path / FILE, victim)
    with pytest.raises(NotAFileOfItsOwn, match=f"{FILE} is a"):
        Store(tmp_path)
    assert untouched(victim)


def test_a_sweeps_parts_folder_that_is_a_link_is_refused(tmp_path):
    from sim.experiments import store

    outside = tmp_path / "elsewhere"
    outside.mkdir()
    os.symlink(outside, tmp_path / store.PARTS)
    with pytest.raises(NotAFileOfItsOwn, match="parts is a symbolic link"):
        store.append(tmp_path, {"run_id": "r0", "value": 1.0})
    assert not list(outside.iterdir())
