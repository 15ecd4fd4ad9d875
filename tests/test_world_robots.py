"""Issue 3: robots other than the c't-Bot are data (a TOML file), run in the world, and bad or
impossible descriptions are refused with messages naming the file, the key and the problem."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bots.ctbot import CTBOT
from bots.spec import RobotSpec, load_robot
from sim.kinematics import integrate_arcs, wheel_arcs_to_arc
from sim.world import World
from sim.world.spec import Wall, WorldSpec

BIG_BOT = """
name = "bigbot"
wheel_diameter = 0.08
track_width = 0.2
body_radius = 0.13
mass = 2.0
skid = [-0.1, 0.0]

[motor]
max_wheel_speed = 10.0
command_max = 100

[mouse]
mount = [0.05, 0.02]
dpi = 800

[[ir]]
name = "front"
position = [0.12, 0.0]

[[ir]]
name = "left"
position = [0.0, 0.12]
direction = 1.5707963267948966
side = "right"

[[line]]
name = "centre"
position = [0.1, 0.0]
"""


def test_a_toml_robot_runs_in_the_world(tmp_path):
    """A robot of another size, sensor layout and mouse mount, loaded from TOML, drives on the exact
    arc, reads its two IR sensors (one looking sideways at a wall 0.5 m away) and its mouse at its
    own mount and resolution."""
    path = tmp_path / "bigbot.toml"
    path.write_text(BIG_BOT)
    spec = load_robot(path)
    assert spec.body_radius == 0.13 and spec.mouse.mount == (0.05, 0.02) and len(spec.ir) == 2 and len(spec.line) == 1
    wall = Wall(((-2.0, 0.5), (2.0, 0.5), (2.0, 0.6), (-2.0, 0.6)))
    world = World(WorldSpec("w", (-3, -3, 3, 3), walls=(wall,)), dt=0.01)
    robot = world.add_robot(spec, (0.0, 0.0, 0.0))
    r = world.read_all()[0]
    assert len(r.ir_raw) == 2 and len(r.line) == 1 and len(r.border) == 0 and len(r.light) == 0
    assert r.ir_raw[1] == robot.ir_curves[1].lookup(0.5 - 0.12)
    assert abs(world.ray_distance(robot, (0.0, 0.12), math.pi / 2) - 0.38) < 1e-12
    commands = np.tile((50.0, 80.0), (200, 1))
    counts = np.zeros(2)
    for c in commands:
        world.step(c[None])
        counts += world.read_all()[0].mouse_counts
    arcs = commands / 100 * 10.0 * 0.01 * 0.04
    s, alpha = wheel_arcs_to_arc(arcs[:, 0], arcs[:, 1], 0.2)
    assert np.abs(world.poses()[0] - integrate_arcs(np.zeros(3), s, alpha)[-1]).max() < 1e-9
    expected = np.array((np.sum(s - alpha * 0.02), np.sum(alpha * 0.05))) * 800 / 0.0254
    assert np.all(np.abs(counts - expected) <= 1)


@pytest.mark.parametrize(
    ("text", "where", "key"),
    [
        ('name = "x"\nwheel_diameter = 0.05\ntrack_width = 0.1\nbody_radius = 0.06\nwheel_size = 3\n', "bad.toml", "wheel_size"),
        (BIG_BOT.replace("dpi = 800", "dpi = 800\nresolution = 2"), "[mouse]", "resolution"),
        (BIG_BOT.replace('side = "right"', 'side = "right"\nrange = 2'), "[[ir]] #2", "range"),
        (BIG_BOT.replace("[motor]", "[motor]\ntop_speed = 3"), "[motor]", "top_speed"),
        ('name = "x"\nwheel_diameter = 0.05\n', "bad.toml", "track_width"),
        ('name = "x"\nwheel_diameter = = 0.05\n', "bad.toml:2:", "TOML syntax"),
    ],
)
def test_bad_robot_toml_names_the_file_and_the_key(tmp_path, text, where, key):
    """Unknown keys, missing keys and TOML syntax errors raise ValueError naming the file and the
    key (or line)."""
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ValueError) as info:
        load_robot(path)
    message = str(info.value)
    assert str(path) in message and where in message and key in message, message


@pytest.mark.parametrize(
    ("changes", "problem"),
    [
        ({"wheel_diameter": -0.05}, "wheel_diameter: must be a number \\(m\\) at least 0.001"),
        ({"wheel_diameter": math.nan}, "wheel_diameter: must be a number \\(m\\) at least 0.001"),
        ({"body_radius": 0.0}, "body_radius: must be a number \\(m\\) at least 0.001"),
        ({"track_width": 0.15}, "track_width: 0.15 m is wider than the body"),
    ],
)
def test_impossible_robots_are_refused(changes, problem):
    """Negative or non-finite sizes and a track wider than the body are refused, naming the robot."""
    fields = {"name": "odd", "wheel_diameter": 0.0567, "track_width": 0.0972, "body_radius": 0.06, **changes}
    with pytest.raises(ValueError, match=problem) as info:
        RobotSpec(**fields)
    assert "'odd'" in str(info.value)
    with pytest.raises(ValueError, match=problem):
        CTBOT.with_changes(**changes)
