"""The contest's rules (sim.contest.rules) against c't-Sim's: seeding so that the fastest two meet
only in the final and the fastest and the third only in a semi-final, as many byes as the first
round leaves, places 1-4 played out, and the preliminary ranking."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.contest.rules import FINAL, THIRD_PLACE, PrelimResult, lowest_level, placings, plan, prelim_order, spread, winner_goes_to


def paths(entries: int) -> dict[int, list[tuple[int, int]]]:
    """For each rank, the games it would play winning every one: where the plan seats it, then
    where each win sends it."""
    seated = {rank: g.key for g in plan(entries) for rank in g.sides if rank is not None}
    out = {}
    for rank in range(entries):
        key, games = seated.get(rank), []
        while key is not None:
            games.append(key)
            key = winner_goes_to(*key)[:2] if winner_goes_to(*key) else None
        out[rank] = games
    return out


def meeting_level(entries: int, a: int, b: int) -> int:
    """The level of the first game that ranks a and b can both reach: where they can meet first."""
    common = [key for key in paths(entries)[a] if key in paths(entries)[b]]
    return common[0][0]


def favourites_win(entries: int) -> dict[tuple[int, int], tuple[int, int]]:
    """Every game's (winner, loser) when the better rank always wins."""
    games = {g.key: list(g.sides) for g in plan(entries)}
    results = {}
    for key in sorted(games, key=lambda k: (k[0] == THIRD_PLACE, -k[0])):  # first round ... final, third place last
        a, b = games[key]
        winner, loser = min(a, b), max(a, b)
        results[key] = (winner, loser)
        if (to := winner_goes_to(*key)) is not None:
            games[to[:2]][to[2]] = winner
        if key[0] == 2 and THIRD_PLACE in {k[0] for k in games}:
            games[(THIRD_PLACE, 1)][key[1] - 1] = loser
    return results


@pytest.mark.parametrize("entries", range(1, 18))
def test_seeding_and_byes_for_1_to_17_entries(entries):
    games = plan(entries)
    if entries == 1:
        assert games == [] and placings(1, {}) == [(1, 0)]
        return
    low = lowest_level(entries)
    assert low < entries <= 2 * low  # the first round is the smallest that holds everyone
    first = [g for g in games if g.level == low]
    byes = 2 * low - entries
    assert len(first) == entries - low  # as few first-round games as needed ...
    seated_later = sorted(r for g in games if g.level < low for r in g.sides if r is not None)
    assert seated_later == list(range(byes))  # ... and the best `byes` entries skip it
    assert sorted(r for g in first for r in g.sides) == list(range(byes, entries))
    for g in games:  # above the first round every game is full: no second bye
        if g.level not in (low, THIRD_PLACE):
            feeders = [(2 * g.level, 2 * g.number - 1 + k) for k in (0, 1)]
            for side, feeder in zip(g.sides, feeders):
                assert (side is None) == any(h.key == feeder for h in games)
    assert meeting_level(entries, 0, 1) == FINAL
    if entries >= 4:
        assert meeting_level(entries, 0, 2) == 2  # the semi-final
        assert meeting_level(entries, 1, 3) == 2
    if entries >= 8:
        assert meeting_level(entries, 0, 4) == 4  # a quarter-final
    places = placings(entries, favourites_win(entries))
    assert [rank for _, rank in places] == list(range(entries))
    assert [p for p, _ in places][: min(entries, 4)] == [1, 2, 3, 4][: min(entries, 4)]


def test_spread_is_c_t_sims_tree_order():
    """c't-Sim's SpreadingTree adds ranks alternately left and right: 8 places read 1 5 3 7 2 6 4 8."""
    assert [r + 1 for r in spread(8)] == [1, 5, 3, 7, 2, 6, 4, 8]
    with pytest.raises(ValueError, match="power of two"):
        spread(6)


def test_twenty_one_players_as_in_c_t_sims_example():
    """c't-Sim's turnierbaum.txt: 21 players fill 5 of the 16 games of the round of 32; 11 byes."""
    games = plan(21)
    assert lowest_level(21) == 16 and len([g for g in games if g.level == 16]) == 5
    assert sum(1 for g in games if g.level == 8 for r in g.sides if r is not None) == 11


def test_places_below_four_are_shared_by_round():
    places = dict((rank, place) for place, rank in placings(8, favourites_win(8)))
    assert [places[r] for r in range(8)] == [1, 2, 3, 4, 5, 5, 5, 5]
    places = dict((rank, place) for place, rank in placings(3, favourites_win(3)))
    assert places == {0: 1, 1: 2, 2: 3}  # three entries: one semi-final, its loser is third


@settings(deadline=None, max_examples=40)
@given(st.integers(2, 70), st.randoms(use_true_random=False))
def test_any_outcomes_give_everyone_one_place(entries, rnd):
    games = {g.key: list(g.sides) for g in plan(entries)}
    results = {}
    for key in sorted(games, key=lambda k: (k[0] == THIRD_PLACE, -k[0])):
        a, b = games[key]
        winner, loser = (a, b) if rnd.random() < 0.5 else (b, a)
        results[key] = (winner, loser)
        if (to := winner_goes_to(*key)) is not None:
            games[to[:2]][to[2]] = winner
        if key[0] == 2 and (THIRD_PLACE, 1) in games:
            games[(THIRD_PLACE, 1)][key[1] - 1] = loser
    places = placings(entries, results)
    assert sorted(rank for _, rank in places) == list(range(entries))
    assert [p for p, _ in places][: min(4, entries)] == [1, 2, 3, 4][: min(4, entries)]
    assert len(results) == entries - 1 + (entries >= 4)  # one game per entry knocked out, and the game for third


def test_preliminary_ranks_arrivals_then_the_way_left_then_time():
    results = [
        PrelimResult(None, 1.5, 60.0),
        PrelimResult(40.0, 0.0, 40.0),
        PrelimResult(None, 0.5, 60.0),
        PrelimResult(None, 0.5, 12.0),  # fell (its run ended early) as near as the one before
        PrelimResult(35.5, 0.0, 35.5),
        PrelimResult(None, math.inf, 60.0),  # no way to its goal: last
    ]
    assert prelim_order(results) == [4, 1, 3, 2, 0, 5]
