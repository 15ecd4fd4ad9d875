"""`ctsim contest`: a class tournament as c't-Sim's (the handler is `sim.contest.cli`)."""

from __future__ import annotations

import argparse
from pathlib import Path

from sim.cli.options import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_TERMINATED, EXIT_USER, add_noise_option, positive, seed, step_size, whole
from sim.run.loop import MAX_DURATION
from sim.world.step import DEFAULT_DT


def add_parser(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    contest = commands.add_parser(
        "contest",
        help="a class tournament as c't-Sim's: preliminary round, seeded knockout, bracket and ranking",
        description="Run a contest as c't-Sim's ContestConductor: every entry alone against the clock, then a seeded knockout "
        "of races between two bots, each from its own start to its own goal; places 1-4 played out. Kept in DIR/contest.sqlite: "
        "run the same command again to resume. Writes each game's recording, bracket.png, bracket.html and ranking.csv.",
        epilog=f"""exit status:
  0    the contest is over (an entry whose controller fails loses its game: that is no error)
  {EXIT_FAILED}    a game could not be played (e.g. a firmware that cannot start); what was decided is kept
  {EXIT_USER}    a user error found before anything ran (bad option, world, entry, another contest in DIR)
  {EXIT_INTERRUPTED}  interrupted by Ctrl-C, {EXIT_TERMINATED} by SIGTERM: run the same command again to resume""",
    )
    contest.add_argument("world", metavar="WORLD", help="the knockout world: two start slots with a goal each (shipped: contest; or a c't-Sim contest parcours)")
    contest.add_argument("entries", nargs="+", metavar="ENTRY",
                         help="[NAME=]SOURCE[,KEY=VALUE...]: a registered controller or FILE.py[:CLASS] with parameters, "
                         "firmware:PATH (a c't-Bot firmware through the bridge; rc5=T:KEY, call=T:NAME(ARGS)), "
                         "or a folder of student submissions (one entry each, sandboxed)")  # fmt: skip
    contest.add_argument("--prelim", metavar="WORLD", help="world of the preliminary round (default: WORLD)")
    contest.add_argument("--time-limit", type=positive(float, MAX_DURATION, "s"), default=120.0, metavar="SECONDS",
                         help="simulated time of a game; a game without an arrival goes to the bot nearer its goal by path (default: 120)")
    contest.add_argument("--seed", type=seed, default=0, help="seed of every game (default: 0)")
    add_noise_option(contest)
    contest.add_argument("--dt", type=step_size, default=DEFAULT_DT, metavar="SECONDS", help=f"simulation step (default: {DEFAULT_DT:g})")
    contest.add_argument("--out", type=Path, metavar="DIR", help="contest folder (default: runs/contest-<world>)")
    contest.add_argument("--jobs", type=whole, metavar="N", help="games in parallel (default: one per core)")
    contest.add_argument("--engine", choices=("processes", "dask", "serial"), default="processes", help="local processes (default), a Dask LocalCluster, or one game after another here")
    contest.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="play on the Dask cluster whose scheduler is there (implies --engine dask)")
    contest.add_argument("--no-record", action="store_true", help="write no recordings of the games")
    contest.set_defaults(handler=cmd_contest)


def cmd_contest(args: argparse.Namespace) -> int:
    from sim.contest.cli import contest_command

    return contest_command(args)
