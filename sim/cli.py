"""The `ctsim` command line: run, play, report, worlds, check, controllers.

User mistakes (bad world files, robot files, controller names or parameters, unwritable folders)
end in one line `ctsim: error: ...` and exit code 2, never a traceback; a controller that fails
mid-run ends the run with exit code 1 after everything up to then has been written.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import sim
from bots.controller import ControllerError
from sim.run import RunError
from sim.world.spec import WorldFileError

DEFAULT_WORLD = "maze"
DEFAULT_CONTROLLER = "solve_maze"
"""The default run: a c't-Bot solving the shipped maze."""
EXIT_USER, EXIT_FAILED, EXIT_INTERRUPTED = 2, 1, 130


class UsageError(Exception):
    """A user mistake found by the CLI itself."""


# --- argument parsing ---------------------------------------------------------------------


class Parser(argparse.ArgumentParser):
    """Bad options get one line, like every other user error (argparse prints the usage too)."""

    def error(self, message: str):
        self.exit(EXIT_USER, f"ctsim: error: {message} (see `{self.prog} --help`)\n")


def _param(text: str) -> tuple[str, str]:
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {text!r}")
    return key.strip(), value.strip()


def _positive(kind: Callable[[str], Any]) -> Callable[[str], Any]:
    def parse(text: str) -> Any:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
        if not (math.isfinite(value) and value > 0):
            raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
        return value

    return parse


def _add_robot_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("world", nargs="?", default=DEFAULT_WORLD, help=f"a shipped world's name (see `ctsim worlds`) or a .toml/.xml world file (default: {DEFAULT_WORLD})")
    parser.add_argument("--robot", default="ctbot", metavar="NAME|FILE.toml", help="robot description: a built-in name (ctbot) or a TOML robot file (default: ctbot)")
    parser.add_argument("--seed", type=int, default=0, help="seed of every random number in the run; same seed, same run (default: 0)")
    parser.add_argument("--dt", type=_positive(float), default=0.01, metavar="SECONDS", help="simulation step (default: 0.01)")
    parser.add_argument("--out", type=Path, metavar="DIR", help="folder for run.rrd, summary.json, TUM/CSV trajectories and figures (default: runs/<world>-<controller>-<time>)")
    parser.add_argument("--live", action="store_true", help="also stream the recording to a rerun viewer it starts; without one the run goes on, recorded to the file")
    parser.add_argument("--connect", metavar="URL", help="also stream the recording to the rerun viewer at URL (e.g. rerun+http://127.0.0.1:9876/proxy)")
    parser.add_argument("--no-report", action="store_true", help="skip the PNG figures")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="ctsim", description="A 2D simulator of c't-Bot style differential-drive robots.")
    parser.add_argument("--version", action="version", version=f"ctsim {sim.__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    run = commands.add_parser(
        "run",
        help="run a world headless and write a recording, trajectories and figures",
        description="Run robots in a world for a duration (or until a goal), headless, and write run.rrd (rerun), "
        "summary.json, one TUM and CSV file per trajectory (truth and each odometry estimate) and PNG figures. "
        "With no arguments: a c't-Bot solving the shipped maze for 60 s.",
    )
    _add_robot_options(run)
    run.add_argument("--controller", action="append", metavar="NAME|FILE.py[:NAME]", help="controller: a registered name (see `ctsim controllers`) or a Python file; repeat for several robots (default: solve_maze)")
    run.add_argument("--param", action="append", type=_param, default=[], metavar="KEY=VALUE", help="controller parameter, repeatable; applies to every robot's controller")
    run.add_argument("--robots", type=int, metavar="N", help="number of robots (default: one per --controller); a single controller is used by all")
    run.add_argument("--duration", type=_positive(float), default=60.0, metavar="SECONDS", help="simulated time to run (default: 60)")
    run.add_argument("--until-goal", action="store_true", help="stop as soon as a robot reaches a goal area")
    run.set_defaults(handler=cmd_run)

    play = commands.add_parser(
        "play",
        help="drive a robot by keyboard in a window (pygame), recording like run",
        description="Open a window on a world and drive a robot with the arrow keys or WASD (space stops, Esc quits). "
        "Sensor readings and odometry estimates are drawn over the map; the session is recorded like `run`.",
    )
    _add_robot_options(play)
    play.add_argument("--frames", type=int, metavar="N", help="quit after N frames (for scripts and tests)")
    play.add_argument("--fps", type=_positive(float), default=60.0, help="frames per second drawn (default: 60)")
    play.add_argument("--speed", type=_positive(float), default=1.0, metavar="FACTOR", help="simulated time per real time: 2 runs twice as fast (default: 1, real time)")
    play.add_argument("--scale", type=_positive(float), default=None, metavar="PX_PER_M", help="pixels per metre (default: fit the world in 900x700)")
    play.set_defaults(handler=cmd_play)

    report = commands.add_parser("report", help="draw the PNG figures of a run folder", description="Draw trajectories.png and errors.png in a folder written by `ctsim run`.")
    report.add_argument("run_dir", type=Path, metavar="RUN_DIR")
    report.set_defaults(handler=cmd_report)

    worlds = commands.add_parser("worlds", help="list the shipped worlds", description="List the shipped worlds: name, size and description.")
    worlds.set_defaults(handler=cmd_worlds)

    check = commands.add_parser("check", help="validate a world file", description="Load a world file and report problems (file:line: problem) or OK with a summary.")
    check.add_argument("world", metavar="WORLD")
    check.set_defaults(handler=cmd_check)

    controllers = commands.add_parser("controllers", help="list the registered controllers and their parameters", description="List the controllers `--controller` accepts by name, with their parameters.")
    controllers.set_defaults(handler=cmd_controllers)
    return parser


# --- helpers --------------------------------------------------------------------------------


def load_robot_spec(name: str):
    """A built-in robot by name or a TOML robot file."""
    from bots.ctbot import ROBOTS
    from bots.spec import load_robot

    if name in ROBOTS:
        return ROBOTS[name]
    if name.endswith(".toml") or Path(name).exists():
        return load_robot(name)
    raise UsageError(f"unknown robot {name!r} (built-in: {', '.join(ROBOTS)}; or a .toml file)")


def _out_dir(out: Path | None, world: str, controller: str) -> Path:
    if out is None:
        stamp = time.strftime("%Y%m%d-%H%M%S")
        out = Path("runs") / f"{Path(world).stem}-{Path(controller.split(':')[0]).stem}-{stamp}"
    out.mkdir(parents=True, exist_ok=True)
    return out


class Progress:
    """tqdm progress bar on stderr over simulated time; shown only on a terminal and only when
    the run takes more than a second."""

    def __init__(self, duration: float, dt: float, every: int = 100):
        self.duration, self.dt, self.every = duration, dt, every
        self.bar: Any = None
        self._count = 0

    def on_start(self, world, logs) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=round(self.duration, 6), unit="s sim", delay=1.0, disable=not sys.stderr.isatty(), leave=False, file=sys.stderr, bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s sim [{elapsed}<{remaining}]")

    def on_sample(self, world, logs) -> None:
        self._count += 1
        if self._count % self.every == 0:
            self.bar.update(world.time - self.bar.n)

    def on_end(self, result) -> None:
        self.bar.close()


# --- run and play ------------------------------------------------------------------------------


def _setups(args: argparse.Namespace, spec) -> list:
    """One RobotSetup per robot from --controller/--robots/--param."""
    from bots.behaviours import make
    from sim.run import RobotSetup

    names = args.controller or [DEFAULT_CONTROLLER]
    count = args.robots if args.robots is not None else len(names)
    if count < 1:
        raise UsageError(f"--robots must be at least 1, got {count}")
    if len(names) not in (1, count):
        raise UsageError(f"{len(names)} controllers for {count} robots; give one, or one per robot")
    names = names * count if len(names) == 1 else names
    params = dict(args.param)
    return [RobotSetup(spec, make(name, params), controller_name=name, params=params) for name in names]


def cmd_run(args: argparse.Namespace) -> int:
    from sim.run import run
    from sim.views.recording import Recorder
    from sim.world.files import load_world

    world = load_world(args.world)
    spec = load_robot_spec(args.robot)
    setups = _setups(args, spec)
    out = _out_dir(args.out, args.world, setups[0].controller_name)
    facts = {"controller parameters": ", ".join(f"{k}={v}" for k, v in args.param) or "defaults", "duration": f"{args.duration:g} s" + (" or until a goal" if args.until_goal else "")}
    recorder = Recorder(out / "run.rrd", live=args.live, connect=args.connect, facts=facts)
    result = run(world, setups, args.duration, dt=args.dt, seed=args.seed, until_goal=args.until_goal, observers=(recorder, Progress(args.duration, args.dt)))
    return finish(result, out, {"duration": args.duration, "until_goal": args.until_goal}, report=not args.no_report)


def cmd_play(args: argparse.Namespace) -> int:
    from sim.views.window import play
    from sim.world.files import load_world

    world = load_world(args.world)
    spec = load_robot_spec(args.robot)
    out = _out_dir(args.out, args.world, "teleop")
    result = play(world, spec, out / "run.rrd", seed=args.seed, dt=args.dt, fps=args.fps, speed=args.speed, frames=args.frames, scale=args.scale, live=args.live, connect=args.connect)
    return finish(result, out, {"duration": result.times[-1] if result.times else 0.0, "until_goal": False}, report=not args.no_report)


def finish(result, out: Path, options: dict[str, Any], report: bool = True) -> int:
    """Write summary.json, TUM/CSV trajectories and figures of a run; print the table and the
    files; the exit code (1 when a controller failed, 130 when interrupted)."""
    written = [out / "run.rrd"]
    summary = summarize(result, options)
    written += write_trajectories(result, out, summary)
    (out / "summary.json").write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")
    written.append(out / "summary.json")
    if report and result.times:
        from sim.views.figures import report_run_dir

        written += report_run_dir(out)
    print(table(summary))
    print("wrote:")
    for path in written:
        print(f"  {path}")
    if result.reason == "error":
        print(f"ctsim: run stopped: {result.error}", file=sys.stderr)
        return EXIT_FAILED
    if result.reason == "interrupted":
        print(f"ctsim: {result.error}; partial results written to {out}", file=sys.stderr)
        return EXIT_INTERRUPTED
    return 0


def summarize(result, options: dict[str, Any]) -> dict[str, Any]:
    """The figures of the table and what produced them, as plain data for summary.json."""
    from dataclasses import asdict

    from sim.analysis.metrics import compare_run, path_lengths

    metrics = compare_run(result) if result.times else {}
    robots = [
        {
            "name": log.name,
            "robot": log.spec.name,
            "controller": log.controller_name,
            "params": log.params,
            "distance": float(path_lengths(log.truth_array())[-1]) if log.truth else 0.0,
            "collisions": log.collisions,
            "fell": log.fell,
            "goal_time": log.goal_time,
            "estimates": {name: asdict(m) for name, m in metrics.get(log.name, {}).items()},
        }
        for log in result.robots
    ]
    return {
        "ctsim_version": sim.__version__,
        "world": {"name": result.world.name, "source": str(result.world.source or result.world.name)},
        "seed": result.seed,
        "dt": result.dt,
        **options,
        "time": result.times[-1] if result.times else 0.0,
        "reason": result.reason,
        "error": result.error,
        "robots": robots,
    }


def write_trajectories(result, out: Path, summary: dict[str, Any]) -> list[Path]:
    """truth.tum and <estimate>.tum (prefixed with the robot name when there are several), and
    the same as CSV; records the TUM names in the summary for `ctsim report`."""
    from sim.analysis.export import write_csv, write_tum

    written = []
    prefix = len(result.robots) > 1
    times = result.time
    for log, entry in zip(result.robots, summary["robots"]):
        tracks = {"truth": log.truth_array(), **log.estimate_arrays()}
        entry["tum"] = {}
        for label, poses in tracks.items():
            stem = f"{log.name}_{label}" if prefix else label
            write_tum(out / f"{stem}.tum", times[: len(poses)], poses)
            write_csv(out / f"{stem}.csv", times[: len(poses)], poses)
            entry["tum"][label] = f"{stem}.tum"
            written += [out / f"{stem}.tum", out / f"{stem}.csv"]
    return written


def table(summary: dict[str, Any]) -> str:
    """The short end-of-run table: per robot distance and collisions, per estimate its errors."""
    lines = [f"{summary['world']['name']}, seed {summary['seed']}, {summary['time']:.2f} s simulated ({summary['reason']})"]
    header = f"{'robot':<12}{'estimate':<12}{'distance m':>11}{'collisions':>11}{'final err m':>12}{'ATE RMS m':>11}{'final hdg °':>12}"
    lines.append(header)
    for robot in summary["robots"]:
        first = f"{robot['name']:<12}{'':<12}{robot['distance']:>11.3f}{robot['collisions']:>11d}"
        notes = [note for note in ("fell into a hole" if robot["fell"] else "", f"goal at {robot['goal_time']:.2f} s" if robot["goal_time"] is not None else "") if note]
        lines.append(first + ("   " + ", ".join(notes) if notes else ""))
        for name, errors in robot["estimates"].items():
            lines.append(f"{'':<12}{name:<12}{'':>11}{'':>11}{errors['final_position_error']:>12.4f}{errors['ate_rmse']:>11.4f}{math.degrees(errors['final_heading_error']):>12.2f}")
    return "\n".join(lines)


# --- listings ---------------------------------------------------------------------------------


def cmd_report(args: argparse.Namespace) -> int:
    from sim.views.figures import report_run_dir

    if not (args.run_dir / "summary.json").is_file():
        raise UsageError(f"{args.run_dir}: not a run folder (no summary.json)")
    for path in report_run_dir(args.run_dir):
        print(path)
    return 0


def cmd_worlds(args: argparse.Namespace) -> int:
    from sim.world.files import load_world, shipped_worlds

    for name, path in shipped_worlds().items():
        world = load_world(path)
        xmin, ymin, xmax, ymax = world.bounds
        print(f"{name:<14}{xmax - xmin:5.2f} x {ymax - ymin:<5.2f} m  {world.description}")
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    from sim.world.files import check_world, load_world

    try:
        warnings = check_world(args.world)
    except WorldFileError as err:
        print(err)
        return EXIT_FAILED
    world = load_world(args.world)
    xmin, ymin, xmax, ymax = world.bounds
    counts = ", ".join(f"{len(getattr(world, k))} {k}" for k in ("walls", "floor", "lines", "holes", "lights", "starts", "goals", "movables"))
    for warning in warnings:
        print(f"{args.world}: warning: {warning}")
    print(f"OK {args.world}: {world.name}, {xmax - xmin:.2f} x {ymax - ymin:.2f} m; {counts}")
    return 0


def cmd_controllers(args: argparse.Namespace) -> int:
    import inspect

    import bots.behaviours  # noqa: F401  (registers the shipped controllers)
    from bots.controller import REGISTRY, parameters


    if not REGISTRY:
        print("no controllers registered")
    for name in sorted(REGISTRY):
        factory = REGISTRY[name]
        shown = [p.name if p.default is inspect.Parameter.empty else f"{p.name}={p.default!r}" for p in parameters(factory).values()]
        doc = (inspect.getdoc(factory) or "").split("\n")[0]
        print(f"{name:<16}{doc}")
        if shown:
            print(f"{'':<16}parameters: {', '.join(shown)}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `ctsim` console script; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return EXIT_USER
    try:
        return args.handler(args)
    except (WorldFileError, ControllerError, UsageError, RunError, ValueError, OSError) as err:
        print(f"ctsim: error: {err}", file=sys.stderr)
        return EXIT_USER
    except KeyboardInterrupt:
        print("ctsim: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
