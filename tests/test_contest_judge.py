"""The contest's judge on hand-made races in a two-lane world (sim.contest.judge, game, paths):
arrival at a robot's own goal, the time limit decided by the way left along the floor, a fall into
a hole and a controller that raises each lose or win as the rules say; and the world pieces the
judge stands on (goals per start slot, a referee that stops the run, named robots)."""

from __future__ import annotations

import math
import textwrap
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from bots.commands import Twist
from bots.controller import FunctionController
from bots.ctbot import CTBOT
from sim.contest.entries import parse
from sim.contest.game import GameJob, play
from sim.contest.judge import Guarded, OverBudget, Side, decide
from sim.contest.paths import PathField
from sim.contest.rules import wall_budget
from sim.run.loop import RobotSetup, run
from sim.world.files import load_world, world_warnings
from sim.world.spec import Goal, Start, WorldFileError

DT = 0.01
LANES = Path(__file__).resolve().parent / "data" / "contest_lanes.toml"
CONTROLLERS = '''
from bots.commands import Twist

class Straight:
    def __init__(self, speed: float = 0.2):
        self.speed = speed
    def step(self, t, readings):
        return Twist(self.speed, 0.0)

class Raiser:
    def step(self, t, readings):
        if t >= 0.5:
            raise RuntimeError("my bug")
        return Twist(0.2, 0.0)

class Hanger:
    def step(self, t, readings):
        while t >= 0.5:
            pass
        return Twist(0.2, 0.0)

class Sleeper:
    def step(self, t, readings):
        if t >= 0.5:
            import time
            time.sleep(0.2)
        return Twist(0.2, 0.0)

class Quitter:
    def step(self, t, readings):
        if t >= 0.5:
            raise SystemExit(0)
        return Twist(0.2, 0.0)
'''


@pytest.fixture
def lanes(tmp_path):
    """A world file of two lanes turned about their centre: slot 1 drives +x to goal 1 1.3 m ahead,
    slot 2 drives -x to goal 2; `extra` TOML adds pieces (a hole)."""

    def make(extra: str = "") -> str:
        path = tmp_path / "lanes.toml"
        path.write_text(LANES.read_text() + textwrap.dedent(extra))
        return str(path)

    (tmp_path / "bots.py").write_text(CONTROLLERS)
    return make


def entries(tmp_path, *texts):
    return tuple(parse([t.replace("bots.py", str(tmp_path / "bots.py")) for t in texts]))


def race(tmp_path, world: str, *texts: str, limit: float = 10.0) -> dict:
    return play(GameJob(2, 1, entries(tmp_path, *texts), world, limit, 0, DT, None))


def test_the_first_body_at_its_own_goal_wins_at_the_step_it_gets_there(lanes, tmp_path):
    """Straight at 0.25 m/s from x = 0.2 m: the centre crosses the goal's edge 1.3 m ahead after 1.3 / 0.25
    = 5.2 s, at the first sample not before it (samples every 10 ms; no motor lag)."""
    outcome = race(tmp_path, lanes(), "slow=bots.py:Straight,speed=0.2", "fast=bots.py:Straight,speed=0.25")
    assert outcome["verdict"]["winner"] == 1 and outcome["verdict"]["reason"] == "goal"
    assert outcome["sides"][1]["arrival"] == pytest.approx(5.2, abs=DT + 1e-9)  # one sample either way of the crossing
    assert outcome["sides"][0]["arrival"] is None and outcome["reason"] == "goal"


def test_without_an_arrival_the_nearer_by_path_wins_at_the_time_limit(lanes, tmp_path):
    outcome = race(tmp_path, lanes(), "slow=bots.py:Straight,speed=0.05", "faster=bots.py:Straight,speed=0.1", limit=3.0)
    verdict, (slow, faster) = outcome["verdict"], outcome["sides"]
    assert verdict["reason"] == "time limit" and verdict["winner"] == 1 and verdict["time"] == pytest.approx(3.0)
    assert "nearer its goal by path" in verdict["text"]
    # straight lanes: the way left is the distance to the goal's edge, 1.3 m less what each drove
    assert slow["distance_left"] == pytest.approx(1.3 - 0.05 * 3.0, abs=0.03)  # grid of 2 cm: a cell at either end
    assert faster["distance_left"] == pytest.approx(1.3 - 0.1 * 3.0, abs=0.03)


def test_a_bot_in_a_hole_loses_at_once_even_ahead(lanes, tmp_path):
    world = lanes("""
        [[hole]]
        box = [0.6, 0.45, 0.9, 0.75]   # across lane 2, 0.9 m ahead of its start
    """)
    outcome = race(tmp_path, world, "careful=bots.py:Straight,speed=0.05", "reckless=bots.py:Straight,speed=0.3")
    verdict = outcome["verdict"]
    assert verdict["winner"] == 0 and verdict["reason"] == "fall" and "reckless fell into a hole" in verdict["text"]
    assert outcome["sides"][1]["fell"] == pytest.approx(verdict["time"]) and outcome["sides"][1]["fell"] < 4.0


def test_a_controller_that_raises_loses_and_its_message_is_kept(lanes, tmp_path):
    outcome = race(tmp_path, lanes(), "buggy=bots.py:Raiser", "steady=bots.py:Straight,speed=0.05")
    verdict = outcome["verdict"]
    assert verdict == {"winner": 1, "reason": "failure", "text": "buggy's controller failed at 0.50 s", "time": 0.5}
    assert "my bug" in outcome["error"] and "bots.py" in outcome["error"]


@pytest.mark.parametrize(("cls", "said"), [("Hanger", "took longer than the step time limit of 1 s"), ("Quitter", "called sys.exit(0)")])
def test_a_controller_that_hangs_or_exits_loses_and_the_game_goes_on(lanes, tmp_path, monkeypatch, cls, said):
    """The run's watchdog (here 1 s a step instead of 30) ends an endless loop; sys.exit is a failure too."""
    monkeypatch.setattr("sim.contest.game.STEP_TIMEOUT", 1.0)
    outcome = race(tmp_path, lanes(), f"stuck=bots.py:{cls}", "steady=bots.py:Straight,speed=0.05")
    assert outcome["verdict"]["winner"] == 1 and outcome["verdict"]["reason"] == "failure" and said in outcome["error"]


def test_what_is_even_goes_to_the_better_preliminary():
    same = Side(None, None, None, 0.8004, 60.0), Side(None, None, None, 0.8, 60.0)
    assert decide(("a", "b"), list(same), 60.0).winner == 0  # within the judge's millimetre
    assert "even by path" in decide(("a", "b"), list(same), 60.0).text
    both = Side(12.5, None, None, 0.0, 12.5), Side(12.5, None, None, 0.0, 12.5)
    assert decide(("a", "b"), list(both), 60.0).winner == 0
    fell = Side(None, 3.0, None, 0.9, 3.0), Side(None, 3.0, None, 0.5, 3.0)
    assert decide(("a", "b"), list(fell), 60.0).winner == 1  # both fell in the same step: the nearer


def test_the_way_left_follows_the_floor_not_the_straight_line(lanes):
    """From lane 1's start the way to goal 2 goes round the dividing wall: here that is impossible
    (the lanes do not meet), so it is infinite; to its own goal it is the straight 1.3 m."""
    world = load_world(lanes())
    own = PathField(world, world.goals_of(1), 0.03)
    other = PathField(world, world.goals_of(2), 0.03)
    assert own.distance(0.2, 0.2) == pytest.approx(1.3, abs=0.03)
    assert math.isinf(other.distance(0.2, 0.2))


def test_a_goal_of_one_slot_is_not_the_others(lanes):
    """A robot from start slot 2 driving through goal 1 does not arrive, one placed by a bare pose
    (no slot) does; `stop_when` ends the run with its reason; robots carry the names given."""
    world = load_world(lanes())
    drive = FunctionController(lambda t, r: Twist(0.25, 0.0))
    setups = [
        RobotSetup(CTBOT, FunctionController(lambda t, r: Twist(0.0, 0.0)), name="red"),
        RobotSetup(CTBOT, drive, start=Start(1.3, 0.2, 0.0, slot=2), name="blue"),
        RobotSetup(CTBOT, drive, start=(1.3, 0.6, 0.0), name="green"),
    ]
    moved = load_world(lanes())
    moved = replace(moved, goals=(*moved.goals, Goal(((1.5, 0.45), (1.8, 0.45), (1.8, 0.75), (1.5, 0.75)), slot=1)))
    result = run(moved, setups, 5.0, stop_when=lambda w, logs: "judged" if w.time >= 1.6 else None)
    assert result.reason == "judged" and result.duration == pytest.approx(1.6)
    assert [log.name for log in result.robots] == ["red", "blue", "green"]
    assert result.robots[0].goal_time is None and result.robots[1].goal_time is None  # blue crossed goal 1: not its own
    assert result.robots[2].goal_time == pytest.approx(0.8, abs=DT + 1e-9)  # no slot: every goal counts (0.2 m at 0.25 m/s)
    assert world.goals_of(2)[0].slot == 2 and len(world.goals_of(None)) == 2


def test_goal_slots_are_checked_in_world_files(lanes, tmp_path):
    world = load_world(lanes('[[goal]]\nbox = [0.9, 0.1, 1.0, 0.2]\nslot = 3\n'))
    assert any("slot 3, but no start has that slot" in w for w in world_warnings(world))
    with pytest.raises(WorldFileError, match=r"lanes.toml:\d+: .*slot"):
        load_world(lanes('[[goal]]\nbox = [0.9, 0.1, 1.0, 0.2]\nslot = -1\n'))


@pytest.mark.parametrize("name", ["contest", "contest_sprint"])
def test_the_shipped_contest_worlds_favour_neither_side(name):
    """The shipped contest worlds are turned, not mirrored: the same right-hand wall follower from
    either start reaches its own goal in the same step; its way left is the same from either start."""
    world = load_world(name)
    (a, b) = world.start_order()
    clearance = 0.5 * CTBOT.body_radius
    ways = [PathField(world, world.goals_of(s.slot), clearance).distance(s.x, s.y) for s in (a, b)]
    assert ways[0] == pytest.approx(ways[1], abs=1e-9) and 2.0 < ways[0] < 8.0
    assert np.allclose([a.x + b.x, a.y + b.y], [world.bounds[2], world.bounds[3]])  # turned about the centre
    outcome = play(GameJob(2, 1, tuple(parse(["a=solve_maze", "b=solve_maze"])), name, 120.0, 0, DT, None, noise="none"))  # the geometry alone: the same exact sensors on both sides
    first, second = outcome["sides"]
    assert first["arrival"] is not None and first["arrival"] == second["arrival"]  # the same step, to the bit


PARCOURS = """<?xml version="1.0" encoding="UTF-8"?>
<world><description>as c't-Sim's contest parcours: two starts, one goal (ZZ) in the top wall</description>
<parcours>
<line>*==ZZ==*</line>
<line>#      #</line>
<line>#      #</line>
<line>#.1  2.#</line>
<line>*======*</line>
</parcours></world>
"""


def test_a_c_t_sim_contest_parcours_gives_both_bots_the_one_goal(tmp_path):
    """c't-Sim's contest-* parcours (read from where the user keeps them) are mirrored, with start
    tiles 1 and 2 and one goal in the top wall: both Z tiles are both bots' goal, and two bots
    standing still are even by path at the time limit (the better seed takes it)."""
    path = tmp_path / "contest-mini.xml"
    path.write_text(PARCOURS)
    world = load_world(path)
    assert [s.slot for s in world.start_order()] == [1, 2] and world.goals_of(1) == world.goals_of(2) == world.goals
    outcome = play(GameJob(2, 1, tuple(parse(["a=stop", "b=stop"])), str(path), 1.0, 0, DT, None))
    a, b = outcome["sides"]
    assert a["distance_left"] == pytest.approx(b["distance_left"], abs=1e-9) and 0.5 < a["distance_left"] < 1.5
    assert outcome["verdict"]["winner"] == 0 and "even by path" in outcome["verdict"]["text"]


def test_an_entry_that_sleeps_through_its_wall_clock_budget_loses(lanes, tmp_path, monkeypatch):
    """Each call under the per-call limit, together over the game's budget (here 1 s instead of
    33 s): the call that overruns it fails the sleeper, at its fifth sleep of 0.2 s or before."""
    monkeypatch.setattr("sim.contest.game.wall_budget", lambda limit: 1.0)
    outcome = race(tmp_path, lanes(), "sleepy=bots.py:Sleeper", "steady=bots.py:Straight,speed=0.05", limit=3.0)
    assert outcome["verdict"]["winner"] == 1 and outcome["verdict"]["reason"] == "failure"
    assert "more than the game's budget of 1 s" in outcome["error"] and outcome["sides"][0]["failed"] <= 0.54 + 1e-9


class Ticking:
    """A controller that takes `cost` seconds of a fake clock per call and can bound its calls."""

    def __init__(self, clock: list[float], cost: float):
        self.clock, self.cost, self.limits = clock, cost, []
        self.time_left = None

    def step(self, t, readings):
        self.limits.append(self.time_left())
        self.clock[0] += self.cost
        return Twist(0.0, 0.0)


def test_the_budget_counts_every_call_and_tells_a_controller_what_is_left():
    clock = [0.0]
    ticking = Ticking(clock, 1.5)
    guard = Guarded(ticking, CTBOT, budget=5.0, clock=lambda: clock[0])
    for k in range(3):
        guard.step(0.01 * k, None)
    with pytest.raises(OverBudget, match="6.0 s of wall-clock time, more than the game's budget of 5 s"):
        guard.step(0.03, None)
    assert ticking.limits == [5.0, 3.5, 2.0, 0.5] and guard.failed_at == 0.03
    with pytest.raises(OverBudget):  # (and every call after it)
        guard.step(0.04, None)
    assert wall_budget(2.0) == 32.0
