"""`ctsim report` on a run folder it cannot trust: a hand-edited summary.json, paths that leave
the folder, devices and pipes for files, a run still going. Each ends in one line naming the
file and the key (exit 2), never a traceback, never a read without end, never a quote of a file
outside the folder."""

from __future__ import annotations

import json
import os
import shutil

import pytest

from sim.cli.entry import main
from sim.folder_lock import hold


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """A real run's folder, written once."""
    out = tmp_path_factory.mktemp("run") / "out"
    assert main(["run", "empty", "--controller", "square", "--duration", "0.2", "--no-report", "--out", str(out)]) == 0
    return out


@pytest.fixture()
def folder(run, tmp_path):
    copy = tmp_path / "copy"
    shutil.copytree(run, copy, ignore=shutil.ignore_patterns(".ctsim.lock"))
    return copy


def edit(folder, change) -> None:
    path = folder / "summary.json"
    summary = json.loads(path.read_text())
    path.write_text(json.dumps(change(summary)))


def report_error(folder, capsys) -> str:
    assert main(["report", str(folder)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ctsim: error: ") and err.count("\n") == 1, err
    return err


def test_a_good_folder_is_reported(folder, capsys):
    assert main(["report", str(folder)]) == 0
    assert (folder / "trajectories.png").is_file() and (folder / "report.html").is_file()


@pytest.mark.parametrize(
    "text, message",
    [
        ("[1, 2]", "summary.json: must be a JSON object (a run's summary), not list"),
        ('{"robots": []}', "summary.json: world: missing"),
        ("[" * 100_000 + "]" * 100_000, "nested deeper than"),
        ('{"x": NaN}', "not strict JSON: NaN is no JSON number"),
        ('{"x": 1', "summary.json:1: Expecting"),
    ],
)
def test_a_summary_of_the_wrong_shape_is_one_line(folder, capsys, text, message):
    (folder / "summary.json").write_text(text)
    assert message in report_error(folder, capsys)


@pytest.mark.parametrize(
    "change, message",
    [
        (lambda s: {**s, "robots": "many"}, "robots: must be a list of tables"),
        (lambda s: {**s, "seed": -1}, "seed: must be a whole number at least 0"),
        (lambda s: {**s, "robots": [{**s["robots"][0], "collisions": "x"}]}, "robots[0].collisions: must be a whole number"),
        (lambda s: {**s, "robots": [{**s["robots"][0], "estimates": {"mouse": {"ate_rmse": "x"}}}]}, "robots[0].estimates.mouse.ate_rmse: must be a number"),
        (lambda s: {**s, "robots": [{k: v for k, v in s["robots"][0].items() if k != "tum"}]}, "no trajectories named"),
    ],
)
def test_a_hand_edited_summary_names_the_key(folder, capsys, change, message):
    edit(folder, change)
    assert message in report_error(folder, capsys)


@pytest.mark.parametrize("name", ["/dev/zero", "../../../../etc/passwd", "sub/truth.tum", ".."])
def test_a_trajectory_outside_the_folder_is_refused_without_reading_it(folder, capsys, name):
    edit(folder, lambda s: {**s, "robots": [{**s["robots"][0], "tum": {"truth": name}}]})
    assert "is not a file name in the run folder" in report_error(folder, capsys)


def test_a_link_to_a_device_or_a_pipe_is_refused_at_once(folder, capsys):
    os.symlink("/dev/zero", folder / "zero.tum")
    os.mkfifo(folder / "pipe.tum")
    for name, kind in (("zero.tum", "a character device"), ("pipe.tum", "a named pipe")):
        edit(folder, lambda s, name=name: {**s, "robots": [{**s["robots"][0], "tum": {"truth": name}}]})
        assert f"not a regular file ({kind})" in report_error(folder, capsys)


def test_a_file_that_is_no_trajectory_is_named_not_quoted(folder, capsys):
    (folder / "truth.tum").write_text("root:x:0:0:root:/root:/bin/bash\n")
    err = report_error(folder, capsys)
    assert "truth.tum: not a TUM trajectory" in err and "root:x" not in err


def test_a_missing_trajectory_is_named(folder, capsys):
    (folder / "truth.tum").unlink()
    assert "truth.tum: missing: summary.json names it" in report_error(folder, capsys)


def test_a_run_still_going_is_said_so(folder, capsys):
    edit(folder, lambda s: {**s, "reason": "running", "robots": []})
    handle = hold(folder, "run")
    try:
        assert f"the run is still going (process {os.getpid()}, ctsim run); report it once it has ended" in report_error(folder, capsys)
    finally:
        handle.close()
    assert "the run ended without finishing its summary" in report_error(folder, capsys)
