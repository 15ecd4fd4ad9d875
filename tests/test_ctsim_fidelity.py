"""Issue 12, part 1: numbers pinned against c't-Sim's own world files (../shared/ctsim)."""

from __future__ import annotations

import pytest
from shared_data import PARCOURS, needs_parcours

from bots.ctbot import CTBOT
from sim.world import World
from sim.world.files import load_world
from sim.world.sensors import cny70_value
from sim.world.spec import WorldFileError

pytestmark = needs_parcours

DIFFUSE_CCFFFF = ["testline", "testline2", "follow_line_enh", "line_shortest_test", "crossings_shortest_way", "testline_crossings", "testparcours3"]
LINE_SENSE = 0x350  # the firmware's line threshold in the sim (bot-local.h)


@pytest.mark.parametrize("name", DIFFUSE_CCFFFF)
def test_floor_reads_the_diffuse_colour(name):
    """These worlds' floor is ambient #606060 but diffuse #CCFFFF: c't-Sim's sensors read 68."""
    world = load_world(PARCOURS / f"{name}.xml")
    assert int(cny70_value(world.floor_colour)) == 68


def test_testline_start_is_not_a_line():
    """On testline the start tile read 903 (above LINE_SENSE) with the ambient colour; diffuse: 68."""
    w = World(load_world(PARCOURS / "testline.xml"))
    w.add_robot(CTBOT)
    readings = w.read_all()[0]
    assert list(readings.line) == [68, 68] and max(readings.line) < LINE_SENSE


def test_maze_floor_and_goal_read_637_and_545():
    """Truncation as c't-Sim: #606060 -> 637 (637.9), the goal #66FF00 -> 545 = GROUND_GOAL."""
    world = load_world(PARCOURS / "maze.xml")
    assert int(cny70_value(world.floor_colour)) == 637
    goal = world.goals[0].vertices
    centre = (sum(x for x, _ in goal) / len(goal), sum(y for _, y in goal) / len(goal))
    w = World(world)
    w.add_robot(CTBOT, (centre[0] - 0.009, centre[1], 0.0))  # line sensors 9 mm ahead: on the centre
    assert list(w.read_all()[0].line) == [545, 545]


def test_a_second_robot_in_maze_is_refused_with_a_clear_message():
    """maze.xml has one start slot; c't-Sim would stack a second bot on the first."""
    w = World(load_world(PARCOURS / "maze.xml"))
    w.add_robot(CTBOT)
    with pytest.raises(WorldFileError, match="no start for robot 2: the world has 1 start slot"):
        w.add_robot(CTBOT)


def test_three_robots_take_c_t_sims_slots_in_order():
    """testparcours2 names slots 1, 2 and the default 0: robots get 1, 2, then 0."""
    world = load_world(PARCOURS / "testparcours2.xml")
    slots = {s.slot: s for s in world.starts}
    w = World(world)
    poses = [tuple(w.add_robot(CTBOT).pose[:2]) for _ in range(3)]
    assert poses == [(slots[k].x, slots[k].y) for k in (1, 2, 0)]


def test_cans_are_30_mm_across():
    world = load_world(PARCOURS / "template.xml")
    assert world.movables and all(can.radius == 0.015 for can in world.movables)


def test_the_png_report_draws_the_cans():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle

    from sim.views.figures import draw_world

    world = load_world(PARCOURS / "template.xml")
    fig, ax = plt.subplots()
    draw_world(ax, world)
    radius = world.movables[0].radius
    cans = [p for p in ax.patches if isinstance(p, Circle) and p.radius == radius]  # starts are circles too
    plt.close(fig)
    assert sorted(tuple(c.center) for c in cans) == sorted(tuple(m.position) for m in world.movables)
    assert all(c.radius == 0.015 for c in cans)
