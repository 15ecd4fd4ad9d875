"""The judge of a race: c't-Sim's LabyrinthJudge with the contest's rules for games that end
without an arrival.

- A robot wins when its body's centre reaches one of its own goal areas (the goals of its start
  slot, `WorldSpec.goals_of`) before the other's does.
- A robot that falls into a hole, or whose controller fails (raises, returns a bad command, a
  firmware that hangs or a sandboxed process that dies or overruns its time), loses at once.
- At the time limit the robot nearer its own goal by path distance (`sim.contest.paths`: the way
  left through the free floor, not the straight line) wins.
- What is still even (both in their goal in the same step, both fallen in the same step, the same
  way left to within `rules.TIE_M`) goes to the better entry of the preliminary round.

`Guarded` wraps each controller so that a failure is pinned on its robot; `Judge` watches the run
(the run loop's `stop_when`, and an observer) and gives the `Verdict` (`decide` for a race, `alone`
for a preliminary run).
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from bots.commands import Command, wheel_speeds_for
from bots.controller import Controller, reset
from bots.readings import Readings
from bots.spec import RobotSpec
from sim.contest.paths import PathField
from sim.contest.rules import TIE_M
from sim.run.samples import RobotLog, RunResult
from sim.world import World

LOG = logging.getLogger("ctsim.contest")
LOG.setLevel(logging.INFO)  # the verdict reaches a recorder's handler whatever the root logger's level


class OverBudget(Exception):
    """An entry's calls took more wall-clock time in one game than `rules.wall_budget` allows."""


class Guarded:
    """A controller whose failure is noted (time and message) before the run loop hears of it.
    The command is checked here as the run loop would check it, so that a bad command, too, is
    pinned on this robot; a failing `reset` (a sandboxed file that does not load) fails the first
    step. Its calls together may take `budget` seconds of wall-clock time (`clock`): the call that
    overruns it fails the entry, and a controller that can bound its own calls (a sandboxed one:
    `time_left`) is told what is left before each."""

    def __init__(self, controller: Controller, spec: RobotSpec, budget: float = math.inf, clock: Callable[[], float] = time.monotonic):
        self.controller, self.spec, self.budget, self.clock = controller, spec, budget, clock
        self.failed_at: float | None = None
        self.spent = 0.0
        self._broken: Exception | None = None
        if hasattr(controller, "time_left"):
            controller.time_left = self.time_left

    def time_left(self) -> float:
        """Wall-clock seconds the entry's calls may still take in this game."""
        return max(0.0, self.budget - self.spent)

    def reset(self, robot: RobotSpec) -> None:
        try:
            self._timed(reset, self.controller, robot)
        except Exception as err:  # the entry's own failure: it loses, the game goes on being judged
            self._broken = err

    def step(self, t: float, readings: Readings) -> Command:
        try:
            if self._broken is not None:
                raise self._broken
            command = self._timed(self.controller.step, t, readings)
            if self.spec.chassis is None:
                wheel_speeds_for(command, self.spec)
        except KeyboardInterrupt:  # Ctrl-C: the contest stops, no one fails
            raise
        except BaseException:  # anything else, sys.exit and the run's step timeout too, is the controller's failure
            self.failed_at = t
            raise
        return command

    def _timed(self, call: Callable[..., Any], *args: Any) -> Any:
        if self.time_left() <= 0.0:
            raise OverBudget(self._over())
        started = self.clock()
        try:
            answer = call(*args)
        finally:  # (a call that raised, a sandbox's timeout among them, fails the entry as it is)
            self.spent += self.clock() - started
        if self.time_left() <= 0.0:
            raise OverBudget(self._over())
        return answer

    def _over(self) -> str:
        return f"its calls took {self.spent:.1f} s of wall-clock time, more than the game's budget of {self.budget:g} s (see docs/contest.md)"


class Judge:
    """Watches one game. As the run loop's `stop_when` it ends the race when a robot is in its own
    goal ('goal') or in a hole ('fall'), remembering when each fell; as an observer, at the end
    (before the recorder closes: put it first) it gives each robot's `Side` and the `Verdict`, and
    says the verdict in the recording's events (through Python logging, which a recorder takes)."""

    def __init__(self, names: tuple[str, ...], guards: list[Guarded], fields: list[PathField], time_limit: float):
        self.names, self.guards, self.fields, self.time_limit = names, guards, fields, time_limit
        self.fell: list[float | None] = [None] * len(names)
        self.race: list[Side] = []
        self.verdict: Verdict | None = None

    def stop_when(self, world: World, logs: list[RobotLog]) -> str | None:
        for i, robot in enumerate(world.robots):
            if robot.fallen and self.fell[i] is None:
                self.fell[i] = world.time
        if any(log.goal_time is not None for log in logs):
            return "goal"
        if any(t is not None for t in self.fell):
            return "fall"
        return None

    def on_end(self, result: RunResult) -> None:
        if result.reason.signalled:
            return  # no verdict: the game is played again
        self.race = []
        for log, guard, fell, field in zip(result.robots, self.guards, self.fell, self.fields):
            x, y, _ = log.truth_array(slice(-1, None))[0]
            self.race.append(Side(log.goal_time, fell, guard.failed_at, field.distance(float(x), float(y)), result.duration))
        if len(self.race) == 2:
            self.verdict = decide(self.names, self.race, self.time_limit)
        else:
            self.verdict = alone(self.names[0], self.race[0], result.error, self.time_limit)
        LOG.info(f"verdict: {self.verdict.text}")


@dataclass(frozen=True)
class Side:
    """How one robot's race went: its arrival (s) at its goal, when it fell into a hole or its
    controller failed (s), and the path distance (m) left to its goal where it stood at the end."""

    arrival: float | None
    fell: float | None
    failed: float | None
    distance_left: float
    end_time: float


@dataclass(frozen=True)
class Verdict:
    """The winner's side (0 or 1; None for a robot alone), how the game was decided ('goal',
    'fall', 'failure', 'time limit'), a sentence saying so, and when (s of simulated time; alone:
    the arrival, or the time its run lasted, by which the preliminary round ranks)."""

    winner: int | None
    reason: str
    text: str
    time: float


def decide(names: tuple[str, str], race: list[Side], time_limit: float) -> Verdict:
    """The verdict on a race of two robots (side 0 is the better entry of the preliminary round,
    who takes what is even)."""
    a, b = race
    end = max(a.end_time, b.end_time)
    if a.arrival is not None or b.arrival is not None:
        if b.arrival is None or (a.arrival is not None and a.arrival <= b.arrival):
            both = " (both in the same step: the better preliminary decides)" if a.arrival == b.arrival else ""
            return Verdict(0, "goal", f"{names[0]} reached its goal at {a.arrival:.2f} s{both}", a.arrival)
        return Verdict(1, "goal", f"{names[1]} reached its goal at {b.arrival:.2f} s", b.arrival)
    if a.failed is not None or b.failed is not None:  # the run loop stops at the first failure: one side
        loser = 0 if a.failed is not None else 1
        return Verdict(1 - loser, "failure", f"{names[loser]}'s controller failed at {race[loser].failed:.2f} s", race[loser].failed)
    if a.fell is not None or b.fell is not None:
        if a.fell is not None and b.fell is not None and a.fell == b.fell:
            winner = _nearer(a, b)
            return Verdict(winner, "fall", f"both fell at {a.fell:.2f} s; {names[winner]} was nearer its goal by path ({_ways(names, race)})", a.fell)
        loser = 0 if b.fell is None or (a.fell is not None and a.fell < b.fell) else 1
        return Verdict(1 - loser, "fall", f"{names[loser]} fell into a hole at {race[loser].fell:.2f} s", race[loser].fell)
    winner = _nearer(a, b)
    even = abs(a.distance_left - b.distance_left) < TIE_M
    how = "even by path; the better preliminary decides" if even else f"{names[winner]} nearer its goal by path"
    return Verdict(winner, "time limit", f"time limit {time_limit:g} s: {how} ({_ways(names, race)})", end)


def _nearer(a: Side, b: Side) -> int:
    return 1 if b.distance_left < a.distance_left - TIE_M else 0


def _ways(names: tuple[str, str], race: list[Side]) -> str:
    return " against ".join(f"{name} {side.distance_left:.2f} m" for name, side in zip(names, race))


def alone(name: str, side: Side, error: str | None, time_limit: float) -> Verdict:
    """How a preliminary run (one robot against the clock) went."""
    left = f"{side.distance_left:.2f} m left by path"
    if side.arrival is not None:
        return Verdict(None, "goal", f"{name} reached its goal at {side.arrival:.2f} s", side.arrival)
    if side.failed is not None:
        return Verdict(None, "failure", f"{name}'s controller failed at {side.failed:.2f} s ({left}): {error}", side.end_time)
    if side.fell is not None:
        return Verdict(None, "fall", f"{name} fell into a hole at {side.fell:.2f} s ({left})", side.end_time)
    return Verdict(None, "time limit", f"time limit {time_limit:g} s: {name} has {left}", side.end_time)
