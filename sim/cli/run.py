"""`ctsim run`: robots in a world, headless, recorded, with their results written to a run folder."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path
from typing import Any

from sim import sanitize
from sim.analysis.run_folder import RunFolder
from sim.analysis.summary import SUMMARY_ROOM, unstarted, write_json
from sim.cli.observers import Progress, StopOnSignal
from sim.cli.options import (
    EXIT_INTERRUPTED,
    EXIT_TERMINATED,
    UsageError,
    add_robot_options,
    add_step_timeout_option,
    add_web_options,
    load_robot_spec,
    param,
    positive,
    robot_options,
    robot_setups,
    whole,
)
from sim.cli.output import finish, out_dir
from sim.cli.view import serve_until_interrupted
from sim.errors import UserError
from sim.run.ending import Ending, Terminated
from sim.run.loop import MAX_DURATION, step_count

DEFAULT_DURATION = 300.0
"""The default run: a c't-Bot solving the shipped maze, until it reaches the goal (at most 300 s)."""


def add_parser(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    """The `run` command's options."""
    run = commands.add_parser(
        "run",
        help="run a world headless and write a recording, trajectories and figures",
        description="Run robots in a world for a duration (or until a goal), headless, and write run.rrd (rerun), "
        "summary.json, one TUM and CSV file per trajectory (truth and each odometry estimate) and PNG figures. "
        "With no arguments: a c't-Bot solving the shipped maze until it reaches the goal.",
    )
    add_robot_options(run)
    run.add_argument("--controller", action="append", metavar="NAME|FILE.py[:NAME]",
                     help="controller: a registered name (see `ctsim controllers`) or a Python file; repeat for several robots (default: solve_maze)")
    run.add_argument("--estimator", action="append", default=[], metavar="FILE.py[:CLASS]|localiser",
                     help="your own odometry estimator (reset(robot, pose), update(readings), pose, optional covariance) beside the shipped ones, in every output (repeatable); "
                          "'localiser': the shipped Monte Carlo localiser, odometry held to the map by the IR sensors")
    run.add_argument("--param", action="append", type=param, default=[], metavar="KEY=VALUE", help="controller parameter, repeatable; applies to every robot's controller")
    run.add_argument("--robots", type=whole, metavar="N", help="number of robots (default: one per --controller); a single controller is used by all")
    run.add_argument("--duration", type=positive(float, MAX_DURATION, "s"), default=DEFAULT_DURATION, metavar="SECONDS", help=f"simulated time to run at most (default: {DEFAULT_DURATION:g})")
    add_step_timeout_option(run, "a controller step or estimator update that takes longer (wall clock) ends the run as that code's error")
    run.add_argument("--isolate", action="store_true",
                     help="run your controller and estimator files in processes of their own (the contest's sandbox), which the run ends at a step's time limit, "
                          "a signal or its end: for code that ignores signals or takes what a run relies on (docs/running.md); they may import numpy, the standard library and bots.commands")
    run.add_argument("--until-goal", action=argparse.BooleanOptionalAction, default=None, help="stop as soon as a robot reaches a goal area (default: on in worlds that have a goal)")
    add_web_options(run, "--web", "also serve rerun's web viewer and stream the run into the page as it runs; after the run, serve until Ctrl-C")
    run.set_defaults(handler=cmd_run)


def cmd_run(args: argparse.Namespace) -> int:
    from bots.odometry.user import load
    from sim.experiments import world
    from sim.experiments.api import with_estimators
    from sim.guards import making
    from sim.run.clock import made_in_time

    step_count(args.duration, args.dt)
    place = world(args.world)
    with ExitStack() as isolation:  # (--isolate: the user's processes, ended after the run)
        controller, estimator = _isolated(args, isolation) if args.isolate else (None, load)
        # the controllers and estimators made before the folder is: a bad file, or one whose constructor fails, is refused first;
        # what a constructor replaces in ctsim is put back at once (`sim.guards.making`)
        with making() as replaced, made_in_time(args.step_timeout):
            setups = with_estimators(robot_setups(args, load_robot_spec(args), len(place.start_order()), controller), [estimator(source) for source in args.estimator])
        for note in replaced:
            print(f"ctsim: note: {note}", file=sys.stderr)
        return _run(args, place, setups)


def _isolated(args: argparse.Namespace, isolation: ExitStack) -> tuple[Callable, Callable]:
    """With --isolate, how the run's controllers and estimators are made: those of the user's
    files in processes of their own (`sim.sandbox.isolated`), entered into `isolation`; the
    shipped ones as without it."""
    from bots.behaviours import make
    from sim.sandbox.isolated import estimator_source, isolated_controller

    def controller(name: str, params: dict[str, str]):
        if not (name.endswith(".py") or ".py:" in name):
            return make(name, params)
        if params:
            raise UsageError(f"--isolate passes no --param to a controller file ({sanitize.name(name, 200)}): give its values defaults in the file")
        if not Path(name.partition(".py")[0] + ".py").is_file():
            make(name, params)  # (says which file is missing, as without --isolate)
        return isolation.enter_context(isolated_controller(name, args.step_timeout))

    return controller, lambda source: estimator_source(source, args.step_timeout, isolation)


def _run(args: argparse.Namespace, place, setups: list) -> int:  # noqa: ANN001 (a WorldSpec)
    """The run of `setups` in `place`: its folder, recording, summary and files; the exit status."""
    from sim.experiments import simulate
    from sim.views.recording.arrow import keep_pandas_out_of_arrow
    from sim.views.recording.recorder import Recorder
    from sim.world.files import world_warnings

    for warning in world_warnings(place):
        print(f"ctsim: warning: {args.world}: {warning}", file=sys.stderr)
    until_goal = bool(place.goals) if args.until_goal is None else args.until_goal
    with _web_viewer(args) as web:  # first: a port in use is refused before the folder is touched
        out = out_dir(args.out, args.world, setups[0].controller_name)
        facts = {"controller parameters": ", ".join(f"{k}={v}" for k, v in args.param) or "defaults", "noise": args.noise,
                 "duration": f"{args.duration:g} s" + (" or until a goal" if until_goal else "")}
        options = {"duration": args.duration, "until_goal": until_goal, **robot_options(args)}
        keep_pandas_out_of_arrow()
        write_json(RunFolder(out).summary, unstarted(place, args.seed, args.dt, options, "running", "the run has not ended"), reserve=SUMMARY_ROOM + 2048 * len(setups))
        if web:
            print(f"ctsim: the run streams into {web.url}", file=sys.stderr, flush=True)
        recorder = Recorder(RunFolder(out).recording, live=args.live, connect=web.grpc_url if web else args.connect, facts=facts)
        with StopOnSignal() as stop:
            try:
                result = simulate(place, *setups, duration=args.duration, dt=args.dt, seed=args.seed, until_goal=until_goal,
                                  observers=(stop.starting, recorder, Progress(args.duration, args.dt), stop), step_timeout=args.step_timeout)
            except KeyboardInterrupt as signalled:  # before the run started: nothing simulated, said so in the summary
                return _stopped_before_start(out, place, args, options, signalled)
            except UserError:  # refused before it started (no room for its trajectories, a sensor curve it cannot read back): no run, no summary
                RunFolder(out).summary.unlink(missing_ok=True)
                raise
            status = finish(result.raw, out, options, report=not args.no_report, export_rate=args.export_rate, metrics={robot.name: robot.metrics for robot in result.robots},
                            stop=stop, recording_error=recorder.write_error)
        if web and not (isinstance(result.reason, Ending) and result.reason.signalled):
            serve_until_interrupted(web)
    return status


def _web_viewer(args: argparse.Namespace):
    """With --web, rerun's web viewer for the run to stream into (served on entering); else
    nothing to enter."""
    from contextlib import nullcontext

    if not args.web:
        if args.host is not None or args.port is not None:
            raise UsageError("--host and --port go with --web")
        return nullcontext()
    if args.live or args.connect:
        raise UsageError("--web serves its own viewer: give it, --live or --connect, not two of them")
    from sim.web.serve import DEFAULT_HOST, DEFAULT_PORT, WebViewer

    return WebViewer(None, args.host or DEFAULT_HOST, DEFAULT_PORT if args.port is None else args.port)


def _stopped_before_start(out: Path, place, args: argparse.Namespace, options: dict[str, Any], signalled: KeyboardInterrupt) -> int:
    """The summary of a run that a signal stopped before its first step."""
    reason = Ending.TERMINATED if isinstance(signalled, Terminated) else Ending.INTERRUPTED
    summary = RunFolder(out).summary
    write_json(summary, unstarted(place, args.seed, args.dt, options, reason, f"{reason} before the first step"))
    print(f"ctsim: {reason} before the first step; wrote {sanitize.name(str(summary), 1000)}", file=sys.stderr)
    return EXIT_TERMINATED if reason is Ending.TERMINATED else EXIT_INTERRUPTED
