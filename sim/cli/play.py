"""`ctsim play`: drive a robot by keyboard in a window, recorded like `run`."""

from __future__ import annotations

import argparse
import os
import sys

from sim.analysis.run_folder import RunFolder
from sim.cli.options import UsageError, add_robot_options, load_robot_spec, positive, robot_options, whole
from sim.cli.output import finish, out_dir


def _has_display() -> bool:
    """Whether a window would be seen: a display server and no headless SDL driver."""

    if os.environ.get("SDL_VIDEODRIVER", "") in ("dummy", "offscreen"):
        return False
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) or sys.platform in ("win32", "darwin")


def add_parser(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    """The `play` command's options."""
    play = commands.add_parser(
        "play",
        help="drive a robot by keyboard in a window (pygame), recording like run",
        description="Open a window on a world and drive a robot with the arrow keys or WASD (space stops, Esc quits). "
        "Sensor readings and odometry estimates are drawn over the map; the session is recorded like `run`. "
        "A click on the map picks the robot up and puts it there (drag to turn it the way you drag): a kidnapping, "
        "which its odometry does not see; with --estimator localiser, watch the localiser lose it and find it again.",
    )
    add_robot_options(play)
    play.add_argument("--estimator", action="append", default=[], metavar="FILE.py[:CLASS]|localiser",
                      help="an estimator beside the shipped ones, as `ctsim run --estimator` (repeatable); 'localiser': the Monte Carlo localiser, its particles drawn")
    play.add_argument("--frames", type=whole, metavar="N", help="quit after N frames (for scripts and tests)")
    play.add_argument("--fps", type=positive(float, 1000.0, "frames/s"), default=60.0, help="frames per second drawn (default: 60)")
    play.add_argument("--speed", type=positive(float, 1e4), default=1.0, metavar="FACTOR", help="simulated time per real time: 2 runs twice as fast (default: 1, real time)")
    play.add_argument("--scale", type=positive(float, 1e5, "px/m"), default=None, metavar="PX_PER_M", help="pixels per metre (default: fit the world in 900x700)")
    play.set_defaults(handler=cmd_play)


def cmd_play(args: argparse.Namespace) -> int:
    from bots.odometry.user import made
    from sim.guards import making
    from sim.views.window import play
    from sim.world.files import load_world

    if args.frames is None and not _has_display():
        raise UsageError("play needs a display to show its window (none found: no DISPLAY, or SDL_VIDEODRIVER is headless); "
                         "for a scripted session without one give --frames N, or use `ctsim run` to simulate headless")
    world = load_world(args.world)
    spec = load_robot_spec(args)
    with making() as replaced:  # (made here, so a bad file or constructor is refused before the window opens)
        estimators = [made(source) for source in args.estimator]
    for note in replaced:
        print(f"ctsim: note: {note}", file=sys.stderr)
    out = out_dir(args.out, args.world, "teleop")
    result = play(world, spec, RunFolder(out).recording, seed=args.seed, dt=args.dt, fps=args.fps, speed=args.speed, frames=args.frames, scale=args.scale,
                  live=args.live, connect=args.connect, estimators=estimators)  # fmt: skip
    return finish(result, out, {"duration": result.duration, "until_goal": False, **robot_options(args)}, report=not args.no_report, export_rate=args.export_rate)
