"""The main job says plainly whether the goal was reached and when: summary.json's robot (its
`goal` sentence, its status 'goal reached'), the console table and report.html's table."""

from __future__ import annotations

from bots.behaviours import make
from bots.ctbot import CTBOT
from sim.analysis.summary import summarize
from sim.cli.output import table
from sim.run.loop import RobotSetup, run
from sim.views.html import summary_table
from sim.world.files import load_world

GOAL_CENTRE = (3.0, 2.76, 0.0)
"""The shipped maze's goal tile ('Z': row 1, column 12 of its 0.24 m tiles)."""


def summary_of(start: tuple[float, float, float] | None, duration: float, world: str = "maze") -> dict:
    result = run(load_world(world), [RobotSetup(CTBOT, make("solve_maze", {}), "solve_maze", start=start, estimators=[])], duration, until_goal=True)
    return summarize(result, {"duration": duration, "until_goal": True}, metrics={})


def test_a_robot_that_reaches_the_goal_is_reported_as_such():
    summary = summary_of(GOAL_CENTRE, 1.0)
    robot = summary["robots"][0]
    assert robot["status"] == "goal reached" and robot["goal"] == "goal reached at 0.0 s"
    assert "goal reached at 0.0 s" in table(summary) and "goal reached at 0.0 s" in summary_table(summary["robots"])


def test_a_robot_that_does_not_reach_the_goal_is_reported_as_such():
    summary = summary_of(None, 0.5)
    robot = summary["robots"][0]
    assert robot["status"] == "running" and robot["goal"] == "goal not reached in 0.5 s"
    assert "time limit reached, goal not reached in 0.5 s" in table(summary)
    assert "goal not reached in 0.5 s" in summary_table(summary["robots"])


def test_a_world_without_a_goal_says_so_at_the_time_limit():
    """(c't-Sim's testparcours4 and 5 have none: a run there ending at the time limit is no failure of solve_maze's.)"""
    summary = summary_of(None, 0.5, "empty")
    assert summary["robots"][0]["goal"] is None
    assert "time limit reached (this world has no goal)" in table(summary)
