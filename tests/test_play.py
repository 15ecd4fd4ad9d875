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


SCALE = 200.0
"""px per metre of the kidnapping tests' window: the maze (0-3.12 m) then lies at px = 10 + 200 x, 10 + 200 (3.12 - y)."""


def _click(x: float, y: float, to: tuple[float, float] | None = None) -> list[pygame.event.Event]:
    """A press at maze point (x, y) and a release there, or at `to` (a drag)."""
    down = (int(10 + SCALE * x), int(10 + SCALE * (3.12 - y)))
    up = down if to is None else (int(10 + SCALE * to[0]), int(10 + SCALE * (3.12 - to[1])))
    return [pygame.event.Event(pygame.MOUSEBUTTONDOWN, button=1, pos=down), pygame.event.Event(pygame.MOUSEBUTTONUP, button=1, pos=up)]


def test_a_click_puts_the_robot_there_and_the_localiser_shows_its_particles(tmp_path):
    """A click at (2.76, 0.36), a room at the maze's far side, puts the robot there at frame 5,
    facing as before (a pixel is 5 mm: the pose within it); a drag at frame 10 from (2.28, 0.36)
    up to (2.28, 0.66) puts it there facing +y; a click into the wall block at (2.76, 0.6) moves
    nothing. The encoders counted nothing of it, and the localiser's particles are drawn in its
    colour (pale: unlikely ones)."""
    from sim.views import palette

    snapshot = tmp_path / "last.png"
    events = {5: _click(2.76, 0.36), 10: _click(2.28, 0.36, to=(2.28, 0.66)), 15: _click(2.76, 0.6)}
    result = play(load_world("maze"), CTBOT, None, frames=20, fps=1000, speed=10, scale=SCALE, events=events, snapshot=snapshot, estimators=["localiser"])
    truth = result.robots[0].truth_array()
    start = truth[0]
    assert np.allclose(truth[4], start)  # (sample k is read before frame k's events)
    assert np.allclose(truth[6, :2], (2.76, 0.36), atol=0.005) and truth[6, 2] == start[2]
    assert np.allclose(truth[11, :2], (2.28, 0.36), atol=0.005) and abs(truth[11, 2] - np.pi / 2) < 1e-9
    assert np.allclose(truth[-1], truth[11])  # the click into the wall moved nothing
    assert np.all(result.robots[0].readings(slice(None))["encoder_ticks"] == 0)  # lifted: the wheels counted nothing
    assert _pixels(snapshot, palette.estimate_colour("localiser")) > 0


def test_play_takes_estimators_on_the_command_line(tmp_path):
    """`ctsim play --estimator localiser` runs it beside the defaults into every output; a file
    that is no estimator is refused before the window opens (exit 2, the file named)."""
    out = tmp_path / "o"
    assert main(["play", "maze", "--frames", "30", "--estimator", "localiser", "--out", str(out), "--no-report"]) == 0
    assert (out / "localiser.tum").is_file()
    bad = tmp_path / "bad.py"
    bad.write_text("x = 1\n")
    assert main(["play", "maze", "--frames", "5", "--estimator", str(bad), "--out", str(tmp_path / "b")]) == 2
    assert not (tmp_path / "b").exists()


def test_a_robot_is_put_only_where_it_can_stand():
    """`World.put_robot` refuses a place outside the world, in a wall or on another robot (the
    message says which) and a robot on a general chassis, and leaves the robot where it was; a
    robot put down keeps its sensors' noise going (its next readings are not its first ones
    again, as `reset_robot`'s would be)."""
    import pytest

    from bots.noise import DEFAULT_NOISE, with_noise
    from bots.wheeled import MECANUM4
    from sim.world import World

    world = World(load_world("maze"), seed=3)
    world.add_robot(with_noise(CTBOT, DEFAULT_NOISE), (0.36, 0.36, 0.0))
    world.add_robot(CTBOT, (2.76, 2.76, 0.0))
    first = world.read_all()[0].ir_raw.copy()  # (deterministic: the world's seed)
    for pose, reason in (((-1.0, 0.36, 0.0), "outside the world"), ((2.76, 0.6, 0.0), "overlap a wall"), ((2.80, 2.76, 0.0), "overlap another body")):
        with pytest.raises(ValueError, match=reason):
            world.put_robot(0, pose)
        assert np.allclose(world.poses()[0], (0.36, 0.36, 0.0))
    for _ in range(20):
        world.step(np.array([[120.0, 120.0], [0.0, 0.0]]))
    world.put_robot(0, (0.36, 0.36, 0.0))
    again = world.read_all()[0]
    assert np.allclose(world.poses()[0], (0.36, 0.36, 0.0)) and not np.array_equal(again.ir_raw, first)
    chassis = World(load_world("chassis_yard"))
    chassis.add_robot(MECANUM4)
    with pytest.raises(ValueError, match="general chassis"):
        chassis.put_robot(0, (1.0, 1.0, 0.0))
