"""The rules of a contest as c't-Sim's ContestConductor ran the c't-Bot contest of October 2006:
pure functions, no simulation and no I/O.

A preliminary round (every entry alone against the clock) ranks the entries; the ranking seeds a
knockout tree so that the fastest and the second fastest can meet only in the final, the fastest
and the third only in a semi-final, and so on (c't-Sim's SpreadingTree); where too few entries fill
the first round, as many as possible get a bye; the losers of the semi-finals play for third place.

Levels are numbered as in c't-Sim's database: 1 the final, 2 the semi-finals, 4 the quarter-finals,
... (a level's number is its count of games when full), 0 the game for third place, -1 the
preliminary round. Entries are named by their rank in the preliminary round, 0 the fastest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

PRELIM, THIRD_PLACE, FINAL = -1, 0, 1
TIE_M = 0.001
"""Path distances (m) closer than this count as equal: a point-symmetric world gives both sides the
same distance up to rounding, and the judge's grid measures no finer."""
WALL_BUDGET_S = 30.0
WALL_BUDGET_PER_SIMULATED_S = 1.0
"""An entry's wall-clock budget in one game (s): its calls (making it, reset, every step)
together may take `WALL_BUDGET_S + WALL_BUDGET_PER_SIMULATED_S * time_limit`, real time and half
a minute on top; the call that overruns it fails the entry, which loses that game. A 2 s game is
over within about a minute, whatever an entry sleeps."""


def wall_budget(time_limit: float) -> float:
    """An entry's wall-clock budget (s) in a game of `time_limit` simulated seconds."""
    return WALL_BUDGET_S + WALL_BUDGET_PER_SIMULATED_S * time_limit


def level_name(level: int) -> str:
    """'final', 'semi-final', 'quarter-final', 'round of 16', ... 'third place', 'preliminary'."""
    names = {PRELIM: "preliminary", THIRD_PLACE: "third place", FINAL: "final", 2: "semi-final", 4: "quarter-final"}
    return names.get(level, f"round of {2 * level}")


@dataclass(frozen=True)
class PrelimResult:
    """An entry's run alone: `arrival` (s) at its goal or None, the path distance (m) left to its goal
    at the end, and the simulated time (s) its run lasted (shorter when it fell or failed)."""

    arrival: float | None
    distance_left: float
    time: float


def prelim_order(results: list[PrelimResult]) -> list[int]:
    """Indices of `results` from fastest to slowest: those that arrived by their time, then the rest
    by the distance left to their goal (nearer first), then by the time their run lasted (as
    c't-Sim orders by finish time, then the way left), then in the order given."""

    def key(i: int) -> tuple:
        r = results[i]
        if r.arrival is not None:
            return (0, r.arrival, 0.0, 0.0, i)
        left = round(r.distance_left / TIE_M) if math.isfinite(r.distance_left) else math.inf  # no way to the goal: last
        return (1, 0.0, left, r.time, i)

    return sorted(range(len(results)), key=key)


def spread(count: int) -> list[int]:
    """Ranks in tree order for a full tree of `count` places (a power of two): rank r sits at the
    bit reversal of r. Ranks 0 and 1 differ in the lowest bit and land in different halves (they can
    meet only in the final), 0 and 2 in the same half but different quarters (a semi-final), 0 and 4
    in different eighths (a quarter-final). This is the order c't-Sim's SpreadingTree builds by
    adding the ranks one by one, alternately to the left and right."""
    bits = count.bit_length() - 1
    if count < 1 or 1 << bits != count:
        raise ValueError(f"a full tree has a power of two places, not {count}")
    order = [0] * count
    for rank in range(count):
        place = int(f"{rank:0{bits}b}"[::-1], 2) if bits else 0
        order[place] = rank
    return order


@dataclass(frozen=True)
class Game:
    """A knockout game: `level`, `number` (1-based within the level, top to bottom of the tree) and
    its two sides, each a rank placed there by the plan or None until the game feeding it is over."""

    level: int
    number: int
    sides: tuple[int | None, int | None]

    @property
    def key(self) -> tuple[int, int]:
        return (self.level, self.number)


def lowest_level(entries: int) -> int:
    """The level of the first round for `entries` (at least 2): half the next power of two."""
    return 1 << max(0, math.ceil(math.log2(entries)) - 1)


def plan(entries: int) -> list[Game]:
    """Every game of the knockout tree for `entries` ranked entries that will be played, first
    round first, the game for third place last (when there are two semi-finals to lose).

    The first round (level L, half the next power of two) has L places above it, seeded by
    `spread(L)` with ranks 0 .. L-1. It needs entries - L games: the ranks that sit in those places
    from entries - (entries - L) * 2 = 2L - entries on play the ranks below L, rank r against
    r + entries - L; the 2L - entries best get a bye into the next round (c't-Sim's
    TournamentTree). One entry plays no game: it wins."""
    if entries < 2:
        return []
    low = lowest_level(entries)
    byes = 2 * low - entries
    places = spread(low)
    games: list[Game] = []
    above: list[int | None] = []  # who sits in each of the L places: a rank (bye) or None (a game's winner)
    for number, rank in enumerate(places, 1):
        if rank < byes:
            above.append(rank)
        else:
            games.append(Game(low, number, (rank, rank + entries - low)))
            above.append(None)
    level = low // 2
    while level >= 1:
        games += [Game(level, k + 1, (above[2 * k], above[2 * k + 1])) for k in range(level)]
        above = [None] * level
        level //= 2
    if entries >= 4:  # two semi-finals are played (with three, one of them is a bye)
        games.append(Game(THIRD_PLACE, 1, (None, None)))
    return games


def winner_goes_to(level: int, number: int) -> tuple[int, int, int] | None:
    """(level, number, side) of the game the winner of game (level, number) plays next; None after
    the final and the game for third place."""
    if level <= FINAL:
        return None
    return (level // 2, (number + 1) // 2, (number - 1) % 2)


def loser_goes_to(level: int, number: int) -> tuple[int, int, int] | None:
    """Where the loser goes: the semi-finals' losers play for third place; everyone else is out."""
    return (THIRD_PLACE, 1, number - 1) if level == 2 else None


def placings(entries: int, results: dict[tuple[int, int], tuple[int, int]]) -> list[tuple[int, int]]:
    """(place, rank) of every entry once the knockout is over, best first. `results` maps each
    played game's key to (winner rank, loser rank). Places 1-4 are played out (the final, the game
    for third place; with three entries the semi-final's loser is third); below them an entry's
    place is shared by everyone who went out in the same round (5 for the quarter-finals' losers),
    listed by their preliminary rank."""
    if entries == 1:
        return [(1, 0)]
    place: dict[int, int] = {}
    out_at: dict[int, int] = {}  # rank -> level it lost at
    for (level, _), (winner, loser) in results.items():
        if level == FINAL:
            place[winner], place[loser] = 1, 2
        elif level == THIRD_PLACE:
            place[winner], place[loser] = 3, 4
        else:
            out_at[loser] = level
    for rank, level in out_at.items():
        if rank not in place:
            place[rank] = level + 1  # the losers of a round of L games share place L + 1 (3 for a lone semi-final's)
    missing = [rank for rank in range(entries) if rank not in place]
    if missing:
        raise ValueError(f"the knockout is not over: no place yet for ranks {missing}")
    return sorted(((p, rank) for rank, p in place.items()), key=lambda pr: pr)
