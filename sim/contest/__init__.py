"""Contests as c't-Sim ran them: a preliminary round against the clock, a seeded knockout tree,
races of two robots judged on arrival, falls, failures and the way left (`ctsim contest`).

    from sim.contest import Settings, conduct, parse
    store = conduct(Settings("contest", "contest", time_limit=60), parse(["a=solve_maze", "b=wander"]), "runs/contest")

Modules: `rules` (seeding, tree, places), `paths` (way left to a goal), `judge`, `entries`
(what races, and how it is run), `game` (one game in any process), `store` (SQLite), `conductor`
(the contest to its end, resumable), `ranking` and `bracket` (what people look at), `cli`.
"""

from sim.contest.conductor import ContestError, Settings, conduct
from sim.contest.entries import Entry, EntryError, parse

__all__ = ["ContestError", "Entry", "EntryError", "Settings", "conduct", "parse"]
