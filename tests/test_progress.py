"""Long work off a terminal says how it goes: a line at the start (a resume says how much was done
before), then at most one every few seconds with the count done and left, the rate and the time
left; sweeps, contests, `lab grade` and the first run's compile all say it."""

from __future__ import annotations

import io

from sim.cli.entry import main
from sim.experiments.progress import Progress, duration


class Clock:
    """Seconds that pass only when a test says so."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_lines_every_interval_with_rate_and_time_left():
    clock, stream = Clock(), io.StringIO()
    progress = Progress(10, done=4, unit="run", what="sweep", stream=stream, interval=5.0, clock=clock)
    clock.now += 2.0
    progress.update()  # 2 s after the start: too soon for a line
    clock.now += 3.0
    progress.update()  # 5 s: 2 runs in 5 s = 0.4 runs/s, 4 left -> 10 s
    clock.now += 1.0
    for _ in range(4):
        progress.update()  # the last one always says so
    assert stream.getvalue().splitlines() == [
        "ctsim: sweep: resuming: 4 of 10 runs already done, 6 to go",
        "ctsim: sweep: 6/10 runs done, 4 left, 0.4 runs/s, about 10 s left",
        "ctsim: sweep: 10/10 runs done, 0 left, 1 runs/s, in 6 s",
    ]


def test_a_fresh_start_says_how_much_there_is():
    stream = io.StringIO()
    Progress(1, unit="game", what="contest", stream=stream)
    assert stream.getvalue() == "ctsim: contest: 1 game to go\n"


def test_durations_read_as_people_say_them():
    assert [duration(s) for s in (0.4, 89, 600, 5400, 9000)] == ["0 s", "89 s", "10 min", "1.5 h", "2.5 h"]


def test_a_sweep_off_a_terminal_says_its_progress_and_a_resume_what_was_done(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text('[base]\nduration = 0.1\nworld = "empty"\ncontroller = "idle"\n[axes]\nseed = [0, 1]\n')
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--engine", "serial"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "ctsim: sweep: 2 runs to go" and err[-1].startswith("ctsim: sweep: 2/2 runs done, 0 left, ")
    spec.write_text('[base]\nduration = 0.1\nworld = "empty"\ncontroller = "idle"\n[axes]\nseed = [0, 1, 2]\n')
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--engine", "serial"]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[0] == "ctsim: sweep: resuming: 2 of 3 runs already done, 1 to go" and err[-1].startswith("ctsim: sweep: 3/3 runs done, 0 left, ")
