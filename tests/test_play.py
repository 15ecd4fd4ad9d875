"""`ctsim play` offscreen: injected key presses drive the robot, the session is recorded."""

from __future__ import annotations

import json
import os

os.environ["SDL_VIDEODRIVER"] = "dummy"
os.environ["SDL_AUDIODRIVER"] = "dummy"

import numpy as np  # noqa: E402
import pygame  # noqa: E402

from bots.ctbot import CTBOT  # noqa: E402
from sim.cli.entry import main  # noqa: E402
from sim.views.window import play  # noqa: E402
from sim.world.files import load_world  # noqa: E402


def _key(kind: int, key: int) -> pygame.event.Event:
    return pygame.event.Event(kind, key=key)


def test_up_arrow_drives_forward(tmp_path):
    events = {10: [_key(pygame.KEYDOWN, pygame.K_UP)], 150: [_key(pygame.KEYUP, pygame.K_UP)]}
    result = play(load_world("empty"), CTBOT, tmp_path / "play.rrd", frames=300, fps=1000, speed=10, events=events)
    truth = result.robots[0].truth_array()
    assert result.reason == "duration" and len(truth) == 301
    assert np.allclose(truth[:10], truth[0])  # nothing pressed yet
    travelled = np.hypot(*(truth[-1, :2] - truth[0, :2]))
    assert 0.2 < travelled < 0.45  # 1.4 s of 0.25 m/s, then stopped
    assert np.allclose(truth[-20:], truth[-1])
    assert (tmp_path / "play.rrd").stat().st_size > 0


def test_escape_quits_and_cli_writes_outputs(tmp_path, monkeypatch, capsys):
    import sim.views.window

    quit_at_frame_5 = {5: [_key(pygame.KEYDOWN, pygame.K_ESCAPE)]}
    original = sim.views.window.play
    monkeypatch.setattr(sim.views.window, "play", lambda *a, **k: original(*a, **{**k, "events": quit_at_frame_5}))
    out = tmp_path / "o"
    assert main(["play", "maze", "--frames", "400", "--out", str(out), "--no-report"]) == 0
    assert (out / "run.rrd").is_file() and (out / "truth.tum").is_file()
    assert json.loads((out / "summary.json").read_text())["reason"] == "quit"
    assert "quit (window closed)" in capsys.readouterr().out


def _pixels(path, colour) -> int:
    """How many pixels of a saved frame have exactly `colour`."""
    image = pygame.surfarray.array3d(pygame.image.load(str(path)))
    return int(np.all(image == colour, axis=-1).sum())


def test_the_window_draws_a_chassis_robot_its_wheels_and_the_icr_of_a_turn(tmp_path):
    from bots.wheeled import CAR
    from sim.views import palette
    from sim.views.chassis_view import body_outline

    frames = {}
    for keys in ((pygame.K_UP,), (pygame.K_UP, pygame.K_LEFT)):
        snapshot = tmp_path / f"{len(keys)}.png"
        result = play(load_world("chassis_yard"), CAR, None, frames=60, fps=1000, speed=1, snapshot=snapshot,
                      events={2: [_key(pygame.KEYDOWN, k) for k in keys]})
        assert result.reason == "duration" and result.robots[0].truth_array()[-1, 0] > 1.6  # drove forward
        frames[keys] = snapshot
    straight, turning = frames.values()
    assert _pixels(straight, palette.WHEEL) > 4 * 3 and _pixels(turning, palette.WHEEL) > 4 * 3  # four wheels, 3 px thick
    assert _pixels(straight, palette.ICR) == 0  # no rotation: the ICR is at infinity
    assert _pixels(turning, palette.ICR) > 20  # a disc of 5 px radius about the ICR
    assert _pixels(turning, palette.TRUTH) > 2 * np.ptp(body_outline(CAR)[:, 0]) * 60  # the car's outline at >= 60 px/m
