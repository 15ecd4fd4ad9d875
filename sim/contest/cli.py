"""`ctsim contest`: the thin handler over the package, called by sim/cli/contest.py."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from sim import sanitize
from sim.contest.bracket import write_html, write_png
from sim.contest.conductor import ContestError, Settings, conduct
from sim.contest.entries import EntryError, parse
from sim.contest.ranking import ranking, table, write_csv
from sim.folder_lock import held

EXIT_FAILED = 1


def world_source(text: str) -> str:
    """A world as the database keeps it: a file by its absolute path (a resumed contest may start
    elsewhere), a shipped world by its name."""
    return str(Path(text).resolve()) if Path(text).is_file() else text


def check_worlds(world: str, prelim: str) -> None:
    """Refuse worlds a contest cannot use: the knockout world needs two start slots, each with a
    goal; the preliminary world one."""
    from sim.world.files import load_world
    from sim.world.spec import WorldFileError

    for source, robots in ((world, 2), (prelim, 1)):
        spec = load_world(source)
        starts = spec.start_order()
        if len(starts) < robots:
            kind = "knockout" if robots == 2 else "preliminary"
            raise WorldFileError(spec.source, None, f"a contest's {kind} world needs {robots} start slot(s), this one has {len(starts)}")
        for start in starts[:robots]:
            if not spec.goals_of(start.slot):
                raise WorldFileError(spec.source, None, f"no goal for the robot from start slot {start.slot} (a [[goal]] with slot = {start.slot} or 0)")


def contest_command(args: argparse.Namespace) -> int:
    """Run or resume the contest; 0 when it is over, 1 when a game could not be played."""
    from sim.experiments.engines import engine

    world = world_source(args.world)
    prelim = world_source(args.prelim) if args.prelim else world
    check_worlds(world, prelim)
    entries = parse(args.entries)
    if args.jobs is not None and args.jobs < 1:
        raise EntryError(f"--jobs must be at least 1, got {args.jobs}")
    out = args.out or Path("runs") / f"contest-{Path(world).stem}"
    settings = Settings(world, prelim, args.time_limit, args.seed, args.dt)
    runner = engine(args.engine, args.jobs, args.scheduler)
    try:
        with held(out, "contest"):  # (a second contest into `out` would play every game twice)
            print(f"ctsim contest: {len(entries)} entries in {sanitize.name(str(out))} (run the same command again to resume after an interruption)", file=sys.stderr, flush=True)
            return _play(settings, entries, out, runner, args)
    finally:
        runner.close()


def _play(settings: Settings, entries: list, out: Path, runner, args: argparse.Namespace) -> int:  # noqa: ANN001 (an engine)
    try:
        store = conduct(settings, entries, out, runner, record=not args.no_record)
    except ContestError as err:
        print(f"ctsim: error: {err}", file=sys.stderr)
        return EXIT_FAILED
    rows = ranking(store)
    print(table(rows))
    written = [write_csv(rows, out / "ranking.csv"), write_png(store, out / "bracket.png"), write_html(store, out / "bracket.html", rows)]
    for path in [store.path, *written]:
        print(f"  wrote {sanitize.name(str(path))}")
    store.close()
    return 0
