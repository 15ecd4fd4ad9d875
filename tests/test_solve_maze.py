"""solve_maze through every maze among the shipped worlds and c't-Sim's parcours whose goal a wall
follower reaches: to the goal, without falling, within a time limit; and through the shipped maze
with the realistic noise preset. Runs stop at the goal; the run loop's estimators are off."""

from __future__ import annotations

from pathlib import Path

import pytest
from shared_data import PARCOURS
from shared_data import needs_parcours as needs_shared

from bots.behaviours import make
from bots.ctbot import CTBOT
from bots.noise import with_noise
from sim.run.loop import RobotSetup, run
from sim.world.files import load_world

LIMIT_S = 300.0
"""Simulated time allowed: the slowest case below (realistic noise, seed 1) needs 244 s at 0.25 m/s."""
SPEED = "0.25"
"""The firmware's BOT_SPEED_FAST (m/s), the speed the cases below are timed at."""

MAZES = [
    pytest.param("maze", "right", id="maze-right"),
    pytest.param("maze", "left", id="maze-left"),
    pytest.param(str(PARCOURS / "maze.xml"), "right", id="ctsim-maze-right", marks=needs_shared),
    pytest.param(str(PARCOURS / "testparcours.xml"), "right", id="testparcours-right", marks=needs_shared),
    pytest.param(str(PARCOURS / "testparcours.xml"), "left", id="testparcours-left", marks=needs_shared),
    pytest.param(str(PARCOURS / "testparcours3.xml"), "right", id="testparcours3-right", marks=needs_shared),
]

EXCLUDED = {
    "angle-world-lamps2.xml": "no goal",
    "freie-flaeche.xml": "no goal (an open floor)",
    "follow_line_enh.xml": "no goal (a line course)",
    "testparcours4.xml": "no goal",
    "testparcours5.xml": "no goal",
    "testparcours2.xml": "not solved yet: holes in the middle and free-standing walls; the right-hand run wanders for 300 s (known failure)",
    "angle-world-lamps.xml": "not a maze: the goal is a gap in the far wall of an open room",
    "lange-gerade.xml": "not a maze: one straight corridor (a speed test)",
    "winzig.xml": "not a maze: a 3 x 5 tile box",
    "template.xml": "not a maze: c't-Sim's catalogue of tiles",
    "testline.xml": "goal at the end of a line course, for the line follower",
    "testline2.xml": "goal at the end of a line course, for the line follower",
    "testline_crossings.xml": "goals on a line network, for the line follower",
    "crossings_shortest_way.xml": "goal on a line network, for the line follower",
    "line_shortest_test.xml": "goals on a line network, for the line follower",
}
"""c't-Sim parcours left out, and why."""


def solve(world: str, hand: str, robot=CTBOT, seed: int = 0):  # noqa: ANN001
    controller = make("solve_maze", {"hand": hand, "speed_m_s": SPEED})
    result = run(load_world(world), [RobotSetup(robot, controller, "solve_maze", estimators=[])], LIMIT_S, seed=seed, until_goal=True)
    assert result.error is None
    return result.robots[0]


@pytest.mark.parametrize(("world", "hand"), MAZES)
def test_solve_maze_reaches_the_goal(world, hand):
    log = solve(world, hand)
    assert log.goal_time is not None
    assert not log.fell


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_realistic_noise_still_reaches_the_goal(seed):
    """Wheel slip, spurious ticks, a wrong track width and wheel diameter, a mouse reading 3.75 % off
    and noisy IR at the firmware's fast speed: the robot averages its looks, takes its heading from
    the encoders corrected against the mouse, and squares up on the walls as it goes (the default
    speed over seeds 0-19: tests/test_solve_maze_noise.py)."""
    log = solve("maze", "right", with_noise(CTBOT, "realistic"), seed=seed)
    assert log.goal_time is not None
    assert not log.fell


@needs_shared
def test_every_parcours_is_tested_or_excluded_with_a_reason():
    tested = {Path(p.values[0]).name for p in MAZES} - {"maze"}
    assert {p.name for p in PARCOURS.glob("*.xml")} - {"defaultoptics.xml"} == tested | set(EXCLUDED)


def test_a_mouse_on_the_axle_line_is_left_out_not_divided_by():
    """A robot whose mouse sits on the wheels' axle (it reads no rotation, as the odometry's
    `mouse_applies` says) runs solve_maze on its encoders; its lever of 0 once raised a
    ZeroDivisionError in the controller's reset."""
    from sim.experiments.api import Bot, simulate

    result = simulate("maze", Bot("solve_maze", changes={"mouse.mount": (0.0, 0.0)}), duration=5.0, seed=1)
    assert result.error is None and result.robots[0].distance > 0.1
