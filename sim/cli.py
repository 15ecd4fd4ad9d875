"""The `ctsim` command line: run, view, play, report, sweep, contest, worlds, check, controllers, lab.

User mistakes (bad world files, robot files, controller names or parameters, unwritable folders)
(`sim.errors.UserError`, or an OSError on a path the command line named) end in one line
`ctsim: error: ...` and exit status 2, never a traceback; a run that fails mid-way exits 1 after
everything up to then has been written; any other exception is a bug in ctsim: its traceback, a
line asking for a report, exit 1 (EXIT_STATUSES lists every status).
"""

from __future__ import annotations

import argparse
import math
import os
import re
import signal
import sys
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

import sim
from bots.noise import NOISE_PRESETS, parse_value
from bots.schema import Field, file_stem, option, parse_number, shown
from sim import sanitize
from sim.analysis.summary import SUMMARY_ROOM, summarize, unstarted, write_json
from sim.errors import UserError
from sim.folder_lock import LOCK, hold
from sim.run.clock import MAX_STEP_TIMEOUT, in_controller
from sim.run.ending import Ending, RunError, Terminated
from sim.run.loop import MAX_DURATION, step_count
from sim.world import compiling
from sim.world.step import DEFAULT_DT, DT_RANGE, StepError, check_dt

DEFAULT_WORLD = "maze"
DEFAULT_CONTROLLER = "solve_maze"
DEFAULT_DURATION = 300.0
"""The default run: a c't-Bot solving the shipped maze, until it reaches the goal (at most 300 s)."""
STEP_TIMEOUT = 5.0
"""Seconds (wall clock) a controller step may take in `ctsim run` (`--step-timeout`)."""
EXIT_FAILED, EXIT_USER, EXIT_INTERRUPTED, EXIT_TERMINATED = 1, 2, 130, 143
EXIT_STATUSES = f"""exit status:
  0    success
  {EXIT_FAILED}    a run that started failed (a controller raised, called sys.exit, returned a bad command
       or overran --step-timeout; or the disk filled up); what was recorded up to then is written;
       or ctsim has a bug: its traceback and a request to report it are printed
  {EXIT_USER}    a user error found before anything ran (bad option, world, robot or controller)
  {EXIT_INTERRUPTED}  interrupted by Ctrl-C; partial results written
  {EXIT_TERMINATED}  terminated by SIGTERM (a job scheduler, `timeout`); partial results written"""


class UsageError(UserError):
    """A user mistake found by the CLI itself."""


# --- argument parsing ---------------------------------------------------------------------


class Parser(argparse.ArgumentParser):
    """Bad options get one line, like every other user error (argparse prints the usage too);
    every --help ends with the exit statuses."""

    def __init__(self, *args: Any, **kwargs: Any):
        kwargs.setdefault("epilog", EXIT_STATUSES)
        kwargs.setdefault("formatter_class", argparse.RawDescriptionHelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        self.exit(EXIT_USER, f"ctsim: error: {message} (see `{self.prog} --help`)\n")


def _param(text: str) -> tuple[str, str]:
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {shown(text)}")
    try:
        parse_value(value.strip())  # (a number of thousands of digits is refused here, naming the option)
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"{key.strip()}: {err}") from None
    return key.strip(), value.strip()


def _whole(text: str) -> int:
    """A whole-number option (at most `bots.schema.MAX_DIGITS` digits)."""
    try:
        return int(parse_number(text, int))
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def _seed(text: str) -> int:
    value = _whole(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a seed of 0 or more, got {value}")
    return value


def _positive(kind: Callable[[str], Any], high: float = 1e9, unit: str = "") -> Callable[[str], Any]:
    """A positive option of `kind` (float or int) up to `high`, checked as a file's value is
    (`bots.schema.option`: NaN, infinities, subnormals and 40+ digit numbers refused)."""
    checked = option(Field("integer" if kind is int else "number", unit, 0, high, above=True), kind)

    def parse(text: str) -> Any:
        try:
            value = parse_number(text, kind)
        except ValueError as err:
            raise argparse.ArgumentTypeError(str(err)) from None
        if not value > 0:
            raise argparse.ArgumentTypeError(f"expected a positive number, got {shown(text)}")
        return checked(text)

    return parse


def _step(text: str) -> float:
    value = _positive(float)(text)
    try:
        check_dt(value)
    except StepError:
        raise argparse.ArgumentTypeError(f"expected a step between {DT_RANGE[0]:g} and {DT_RANGE[1]:g} s, got {text!r}") from None
    return value


def _folder(text: str) -> Path:
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a folder, got an empty name")
    return Path(text)


def _add_robot_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("world", nargs="?", default=DEFAULT_WORLD, help=f"a shipped world's name (see `ctsim worlds`) or a .toml/.xml world file (default: {DEFAULT_WORLD})")
    parser.add_argument("--robot", default="ctbot", metavar="NAME|FILE.toml",
                        help="robot description: a built-in name (ctbot, omni3, mecanum4, car, ocp_vehicle) or a TOML robot file (default: ctbot)")
    parser.add_argument("--seed", type=_seed, default=0, help="seed of every random number in the run (the noise of --noise realistic or harsh); same seed, same run (default: 0)")
    parser.add_argument("--noise", choices=NOISE_PRESETS, default="realistic",
                        help="sensor and odometry noise of the robot: realistic (the c't-Bot's figures and their sources, see bots/noise.py), harsh, "
                        "or none (exact sensors, for checks against closed forms) (default: realistic)")
    parser.add_argument("--robot-set", action="append", type=_param, default=[], metavar="SECTION.FIELD=VALUE",
                        help="override one field of the robot description after --noise, repeatable: encoders.slip_std=0.02, mouse.dpi=415, ir.noise_std=0")
    parser.add_argument("--dt", type=_step, default=DEFAULT_DT, metavar="SECONDS", help=f"simulation step (default: {DEFAULT_DT:g})")
    parser.add_argument("--out", type=_folder, metavar="DIR", help="folder for run.rrd, summary.json, TUM/CSV trajectories and figures (default: runs/<world>-<controller>-<time>)")
    parser.add_argument("--live", action="store_true", help="also stream the recording to a rerun viewer it starts; without one the run goes on, recorded to the file")
    parser.add_argument("--connect", metavar="URL", help="also stream the recording to the rerun viewer at URL (e.g. rerun+http://127.0.0.1:9876/proxy)")
    parser.add_argument("--no-report", action="store_true", help="skip the PNG figures")
    parser.add_argument("--export-rate", type=_positive(float, 1e6, "Hz"), metavar="HZ",
                        help="samples per second in the TUM and CSV files (default: every step; run.parquet always holds every sample)")


def _add_web_options(parser: argparse.ArgumentParser, flag: str | None = None, flag_help: str = "") -> None:
    from sim.web.serve import DEFAULT_HOST, DEFAULT_PORT

    if flag:
        parser.add_argument(flag, action="store_true", help=flag_help)
    parser.add_argument("--host", default=None, help=f"address to serve the page on (default: {DEFAULT_HOST}, this machine only; 0.0.0.0 for every network)")
    parser.add_argument("--port", type=_whole, default=None, help=f"the page's port; the recording is served on the next one (default: {DEFAULT_PORT}; 0: two free ones)")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="ctsim", description="A 2D simulator of c't-Bot style differential-drive robots.")
    parser.add_argument("--version", action="version", version=f"ctsim {sim.__version__}")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND")

    run = commands.add_parser(
        "run",
        help="run a world headless and write a recording, trajectories and figures",
        description="Run robots in a world for a duration (or until a goal), headless, and write run.rrd (rerun), "
        "summary.json, one TUM and CSV file per trajectory (truth and each odometry estimate) and PNG figures. "
        "With no arguments: a c't-Bot solving the shipped maze until it reaches the goal.",
    )
    _add_robot_options(run)
    run.add_argument("--controller", action="append", metavar="NAME|FILE.py[:NAME]",
                     help="controller: a registered name (see `ctsim controllers`) or a Python file; repeat for several robots (default: solve_maze)")
    run.add_argument("--estimator", action="append", default=[], metavar="FILE.py[:CLASS]",
                     help="your own odometry estimator (reset(robot, pose), update(readings), pose, optional covariance) beside the shipped ones, in every output (repeatable)")
    run.add_argument("--param", action="append", type=_param, default=[], metavar="KEY=VALUE", help="controller parameter, repeatable; applies to every robot's controller")
    run.add_argument("--robots", type=_whole, metavar="N", help="number of robots (default: one per --controller); a single controller is used by all")
    run.add_argument("--duration", type=_positive(float, MAX_DURATION, "s"), default=DEFAULT_DURATION, metavar="SECONDS", help=f"simulated time to run at most (default: {DEFAULT_DURATION:g})")
    run.add_argument("--step-timeout", type=_positive(float, MAX_STEP_TIMEOUT, "s"), default=STEP_TIMEOUT, metavar="SECONDS",
                     help=f"a controller step that takes longer (wall clock) ends the run as the controller's error (default: {STEP_TIMEOUT:g})")
    run.add_argument("--until-goal", action=argparse.BooleanOptionalAction, default=None, help="stop as soon as a robot reaches a goal area (default: on in worlds that have a goal)")
    _add_web_options(run, "--web", "also serve rerun's web viewer and stream the run into the page as it runs; after the run, serve until Ctrl-C")
    run.set_defaults(handler=cmd_run)

    view = commands.add_parser(
        "view",
        help="serve a run's recording and rerun's web viewer to a browser",
        description="Serve a run's recording (RUN_DIR/run.rrd or a .rrd file) with rerun's web viewer, laid out as in the "
        "native viewer, and print the page's address; serves until Ctrl-C. Nothing to install but ctsim and a browser.",
    )
    view.add_argument("recording", type=Path, metavar="RUN_DIR|RUN.rrd")
    _add_web_options(view)
    view.set_defaults(handler=cmd_view)

    play = commands.add_parser(
        "play",
        help="drive a robot by keyboard in a window (pygame), recording like run",
        description="Open a window on a world and drive a robot with the arrow keys or WASD (space stops, Esc quits). "
        "Sensor readings and odometry estimates are drawn over the map; the session is recorded like `run`.",
    )
    _add_robot_options(play)
    play.add_argument("--frames", type=_whole, metavar="N", help="quit after N frames (for scripts and tests)")
    play.add_argument("--fps", type=_positive(float, 1000.0, "frames/s"), default=60.0, help="frames per second drawn (default: 60)")
    play.add_argument("--speed", type=_positive(float, 1e4), default=1.0, metavar="FACTOR", help="simulated time per real time: 2 runs twice as fast (default: 1, real time)")
    play.add_argument("--scale", type=_positive(float, 1e5, "px/m"), default=None, metavar="PX_PER_M", help="pixels per metre (default: fit the world in 900x700)")
    play.set_defaults(handler=cmd_play)

    report = commands.add_parser("report", help="draw the PNG figures and report.html of a run folder",
                                 description="Draw trajectories.png, errors.png and report.html (one self-contained page: table, figures, facts) in a folder written by `ctsim run`.")
    report.add_argument("run_dir", type=Path, metavar="RUN_DIR")
    report.set_defaults(handler=cmd_report)

    worlds = commands.add_parser("worlds", help="list the shipped worlds", description="List the shipped worlds: name, size and description.")
    worlds.set_defaults(handler=cmd_worlds)

    check = commands.add_parser("check", help="validate a world file", description="Load a world file and report problems (file:line: problem) or OK with a summary.")
    check.add_argument("world", metavar="WORLD")
    check.set_defaults(handler=cmd_check)

    _add_bridge_parser(commands)
    _add_sweep_parser(commands)

    controllers = commands.add_parser("controllers", help="list the registered controllers and their parameters",
                                      description="List the controllers `--controller` accepts by name, with their parameters.")
    controllers.set_defaults(handler=cmd_controllers)
    _add_lab(commands)
    _add_contest(commands)
    return parser


def _add_lab(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    from sim.lab.arguments import add_parser

    add_parser(commands, cmd_lab)


def _add_contest(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
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
    contest.add_argument("--time-limit", type=_positive(float, MAX_DURATION, "s"), default=120.0, metavar="SECONDS",
                         help="simulated time of a game; a game without an arrival goes to the bot nearer its goal by path (default: 120)")
    contest.add_argument("--seed", type=_seed, default=0, help="seed of every game (default: 0)")
    contest.add_argument("--dt", type=_step, default=DEFAULT_DT, metavar="SECONDS", help=f"simulation step (default: {DEFAULT_DT:g})")
    contest.add_argument("--out", type=Path, metavar="DIR", help="contest folder (default: runs/contest-<world>)")
    contest.add_argument("--jobs", type=_whole, metavar="N", help="games in parallel (default: one per core)")
    contest.add_argument("--engine", choices=("processes", "dask", "serial"), default="processes", help="local processes (default), a Dask LocalCluster, or one game after another here")
    contest.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="play on the Dask cluster whose scheduler is there (implies --engine dask)")
    contest.add_argument("--no-record", action="store_true", help="write no recordings of the games")
    contest.set_defaults(handler=cmd_contest)


def cmd_contest(args: argparse.Namespace) -> int:
    from sim.contest.cli import contest_command

    return contest_command(args)


def cmd_lab(args: argparse.Namespace) -> int:
    from sim.lab.cli import lab_command

    return lab_command(args)


# --- helpers --------------------------------------------------------------------------------


def load_robot_spec(args: argparse.Namespace):
    """The robot of --robot (a built-in name or a TOML robot file) with --noise and --robot-set,
    looked up and changed as the Python API does (`sim.experiments.api.robot`)."""
    from sim.experiments.api import robot

    return robot(args.robot, {key: parse_value(value) for key, value in args.robot_set}, args.noise)


RUN_FILES = ("run.rrd", "run.parquet", "summary.json", "report.html", "trajectories.png", "errors.png")
"""The files every run writes into its folder by these names (its trajectories are named in its
summary.json): when a folder of an earlier run is reused, these and the trajectories its summary
names are removed first, so that nothing stale is left beside the new results; nothing else."""
START = Path.cwd()
"""The folder ctsim started in: a relative --out is taken from here, so that a controller that
changes the current folder when it loads cannot move the run's folder."""


def _out_dir(out: Path | None, world: str, controller: str) -> Path:
    if out is None:
        stamp = time.strftime("%Y%m%d-%H%M%S")
        out = Path("runs") / f"{file_stem(Path(world).stem) or 'world'}-{file_stem(Path(controller.split(':')[0]).stem) or 'run'}-{stamp}"
    out = START / out
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise UsageError(f"{out}: cannot make the run's folder: {err.strerror or err}") from None
    _lock(out)
    for stale in _earlier_run(out):
        stale.unlink(missing_ok=True)
    return out


def _earlier_run(out: Path) -> list[Path]:
    """The files an earlier run wrote into `out` (what its summary.json names, and RUN_FILES);
    UsageError for a folder of other files, which ctsim leaves alone."""
    from sim.analysis.run_folder import RunFolderError, read_summary, written_by_ctsim

    present = [p for p in out.iterdir() if p.name != LOCK]
    if not present:
        return []
    try:
        summary = read_summary(out)
    except RunFolderError:
        summary = None
    if summary is None:
        if not written_by_ctsim(out):
            names = ", ".join(sorted(sanitize.name(p.name) for p in present)[:3])
            raise UsageError(f"--out {out} holds files that no ctsim run wrote ({names}{', ...' if len(present) > 3 else ''}): "
                             "give a new or empty folder, or the folder of an earlier run")
        return [out / name for name in RUN_FILES]  # (an earlier run cut short: its fixed files only)
    named = [out / name for robot in summary["robots"] for name in robot.get("tum", {}).values()]
    return [out / name for name in RUN_FILES] + named + [p.with_suffix(".csv") for p in named]


_held: list[Any] = []  # the open lock files of this command, closed (released) when it ends


def _lock(out: Path) -> None:
    """Hold `out` for this run (`sim.folder_lock`): a second run into it is refused."""
    handle = hold(out, "run")
    if handle is not None:
        _held.append(handle)


def _terminate(signum: int, frame: Any) -> None:
    raise Terminated


class StopOnSignal:
    """Run observer and context for Ctrl-C and SIGTERM, by phase (`phase`):

    - "setup" (loading, building the world): a signal stops at once; nothing is written yet.
    - "run" (from the run's start): a signal asks the run to stop at the next step boundary. A
      signal raised wherever the process happens to be (inside rerun's stream, a compiled kernel, a
      socket call) can leave a lock held, and the run would hang instead of writing what it has.
      Inside a controller step (`sim.run.clock.in_controller`) it stops at once: a controller that blocks
      must not make the run deaf. A second signal stops at once.
    - "write" (summary and trajectories): signals are only noted, so those files are whole.
    - "draw" (figures): a signal stops at once; the figures can be drawn later (`ctsim report`).
    """

    def __init__(self) -> None:
        self.received: int | None = None
        self.phase = "setup"
        self._previous: dict[int, Any] = {}
        self.starting = _Starting(self)
        """An observer to put first: the run has started (its on_start) when it is called."""

    def __enter__(self) -> StopOnSignal:
        self._previous = {s: signal.signal(s, self._handle) for s in (signal.SIGINT, signal.SIGTERM)}
        return self

    def __exit__(self, *exc: Any) -> None:
        for number, handler in self._previous.items():
            signal.signal(number, handler)

    def _handle(self, signum: int, frame: Any) -> None:
        first = self.received is None
        self.received = self.received or signum
        if self.phase in ("setup", "draw") or (self.phase == "run" and (not first or in_controller())):
            self._raise(signum)

    @staticmethod
    def _raise(signum: int) -> None:
        raise Terminated if signum == signal.SIGTERM else KeyboardInterrupt

    def status(self) -> int | None:
        """The exit status a signal received so far asks for (None: none received)."""
        return None if self.received is None else EXIT_TERMINATED if self.received == signal.SIGTERM else EXIT_INTERRUPTED

    def on_sample(self, world: Any, logs: Any) -> None:
        if self.received is not None:
            self._raise(self.received)

    def on_end(self, result: Any) -> None:
        self.phase = "write"


class _Starting:
    """The observer that moves a StopOnSignal from "setup" to "run"."""

    def __init__(self, stop: StopOnSignal):
        self.stop = stop

    def on_start(self, world: Any, logs: Any) -> None:
        self.stop.phase = "run"


class Progress:
    """tqdm progress bar on stderr over simulated time; shown only on a terminal and only when
    the run takes more than a second."""

    def __init__(self, duration: float, dt: float, every: int = 100):
        self.duration, self.dt, self.every = duration, dt, every
        self.bar: Any = None
        self._count = 0

    def on_start(self, world, logs) -> None:
        from tqdm import tqdm

        self.bar = tqdm(total=round(self.duration, 6), unit="s sim", delay=1.0, disable=not sys.stderr.isatty(), leave=False, file=sys.stderr,
                        bar_format="{l_bar}{bar}| {n:.1f}/{total:.1f} s sim [{elapsed}<{remaining}]")

    def on_sample(self, world, logs) -> None:
        self._count += 1
        if self._count % self.every == 0:
            self.bar.update(world.time - self.bar.n)

    def on_end(self, result) -> None:
        if self.bar is not None:  # (None when the run stopped before it started)
            self.bar.close()


# --- run and play ------------------------------------------------------------------------------


def _setups(args: argparse.Namespace, spec, room: int) -> list:
    """One RobotSetup per robot from --controller/--robots/--param; the world has start slots for
    `room` robots (one slot each)."""
    from bots.behaviours import make
    from sim.run.loop import RobotSetup

    names = args.controller or [DEFAULT_CONTROLLER]
    count = args.robots if args.robots is not None else len(names)
    if count < 1:
        raise UsageError(f"--robots must be at least 1, got {count}")
    if count > room:
        raise UsageError(f"{count} robots, but the world has room for {room} (one start slot each); add starts (slot 1, 2, ...) to the world")
    if len(names) not in (1, count):
        raise UsageError(f"{len(names)} controllers for {count} robots; give one, or one per robot")
    names = names * count if len(names) == 1 else names
    params = dict(args.param)
    return [RobotSetup(spec, make(name, params), controller_name=name, params=params) for name in names]


def cmd_run(args: argparse.Namespace) -> int:
    from bots.odometry.user import load
    from sim.experiments import simulate, world
    from sim.views.recording.arrow import keep_pandas_out_of_arrow
    from sim.views.recording.recorder import Recorder
    from sim.world.files import world_warnings

    step_count(args.duration, args.dt)
    place = world(args.world)
    setups = _setups(args, load_robot_spec(args), len(place.start_order()))
    extra = [load(source) for source in args.estimator]  # (before the folder is made: a bad file is refused first)
    for warning in world_warnings(place):
        print(f"ctsim: warning: {args.world}: {warning}", file=sys.stderr)
    until_goal = bool(place.goals) if args.until_goal is None else args.until_goal
    with _web_viewer(args) as web:  # first: a port in use is refused before the folder is touched
        out = _out_dir(args.out, args.world, setups[0].controller_name)
        facts = {"controller parameters": ", ".join(f"{k}={v}" for k, v in args.param) or "defaults", "noise": args.noise,
                 "duration": f"{args.duration:g} s" + (" or until a goal" if until_goal else "")}
        options = {"duration": args.duration, "until_goal": until_goal, **_robot_options(args)}
        keep_pandas_out_of_arrow()
        write_json(out / "summary.json", unstarted(place, args.seed, args.dt, options, "running", "the run has not ended"), reserve=SUMMARY_ROOM + 2048 * len(setups))
        if web:
            print(f"ctsim: the run streams into {web.url}", file=sys.stderr, flush=True)
        recorder = Recorder(out / "run.rrd", live=args.live, connect=web.grpc_url if web else args.connect, facts=facts)
        with StopOnSignal() as stop:
            try:
                result = simulate(place, *setups, duration=args.duration, dt=args.dt, seed=args.seed, until_goal=until_goal,
                                  observers=(stop.starting, recorder, Progress(args.duration, args.dt), stop), step_timeout=args.step_timeout,
                                  estimators=extra)
            except KeyboardInterrupt as signalled:  # before the run started: nothing simulated, said so in the summary
                return _stopped_before_start(out, place, args, options, signalled)
            except RunError:  # refused before it started (no room for its trajectories): no run, no summary
                (out / "summary.json").unlink(missing_ok=True)
                raise
            status = finish(result.raw, out, options, report=not args.no_report, export_rate=args.export_rate, metrics={robot.name: robot.metrics for robot in result.robots},
                            stop=stop, recording_error=recorder.write_error)
        if web and not (isinstance(result.reason, Ending) and result.reason.signalled):
            _serve_until_interrupted(web)
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


def _serve_until_interrupted(web, what: str = "") -> None:
    """Serve until Ctrl-C, which is then the normal end (SIGTERM ends as everywhere else)."""
    from sim.run.ending import Terminated

    print(f"ctsim: serving {what}{web.url} until Ctrl-C", flush=True)
    try:
        web.wait()
    except KeyboardInterrupt as stop:
        if isinstance(stop, Terminated):
            raise
    print("ctsim: stopped serving", file=sys.stderr)


def cmd_view(args: argparse.Namespace) -> int:
    from sim.web.serve import DEFAULT_HOST, DEFAULT_PORT, WebViewer, recording_of

    recording = recording_of(args.recording)
    with WebViewer(recording, args.host or DEFAULT_HOST, DEFAULT_PORT if args.port is None else args.port) as web:
        _serve_until_interrupted(web, f"{recording} at ")
    return 0


def _stopped_before_start(out: Path, place, args: argparse.Namespace, options: dict[str, Any], signalled: KeyboardInterrupt) -> int:
    """The summary of a run that a signal stopped before its first step."""
    reason = Ending.TERMINATED if isinstance(signalled, Terminated) else Ending.INTERRUPTED
    write_json(out / "summary.json", unstarted(place, args.seed, args.dt, options, reason, f"{reason} before the first step"))
    print(f"ctsim: {reason} before the first step; wrote {out / 'summary.json'}", file=sys.stderr)
    return EXIT_TERMINATED if reason is Ending.TERMINATED else EXIT_INTERRUPTED


def _robot_options(args: argparse.Namespace) -> dict[str, Any]:
    """The robot options of a run for its summary."""
    return {"robot": args.robot, "noise": args.noise, "robot_set": {key: parse_value(value) for key, value in args.robot_set}}


def _has_display() -> bool:
    """Whether a window would be seen: a display server and no headless SDL driver."""
    import os

    if os.environ.get("SDL_VIDEODRIVER", "") in ("dummy", "offscreen"):
        return False
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) or sys.platform in ("win32", "darwin")


def cmd_play(args: argparse.Namespace) -> int:
    from sim.views.window import play
    from sim.world.files import load_world

    if args.frames is None and not _has_display():
        raise UsageError("play needs a display to show its window (none found: no DISPLAY, or SDL_VIDEODRIVER is headless); "
                         "for a scripted session without one give --frames N, or use `ctsim run` to simulate headless")
    world = load_world(args.world)
    spec = load_robot_spec(args)
    out = _out_dir(args.out, args.world, "teleop")
    result = play(world, spec, out / "run.rrd", seed=args.seed, dt=args.dt, fps=args.fps, speed=args.speed, frames=args.frames, scale=args.scale, live=args.live, connect=args.connect)
    return finish(result, out, {"duration": result.duration, "until_goal": False, **_robot_options(args)}, report=not args.no_report, export_rate=args.export_rate)


def finish(result, out: Path, options: dict[str, Any], report: bool = True, metrics: dict[str, dict[str, dict]] | None = None,
           stop: StopOnSignal | None = None, recording_error: str | None = None, export_rate: float | None = None) -> int:
    """Write summary.json (first: it holds the figures and is small), TUM/CSV trajectories and
    figures of a run; print the table and the files; the exit status (EXIT_STATUSES). A full
    disk or an I/O error ends it with one line and exit 1, having written what fit. `metrics`:
    robot -> estimator -> metrics as a dict, where the caller has them already (else they are
    computed here). With `stop`, a signal received so far skips the figures, one received while
    they are drawn stops them, and either sets the status. `recording_error`: why the recording
    is incomplete (an I/O error too). `export_rate`: samples per second in the TUM and CSV files
    (None: every sample)."""
    written = [out / "run.rrd"]
    summary = summarize(result, options, metrics)
    try:
        write_json(out / "summary.json", summary)
        written.append(out / "summary.json")
        written += write_trajectories(result, out, summary, export_rate)
        write_json(out / "summary.json", summary)  # again, now naming the TUM files
        if report and len(result) and stop is not None and stop.received is not None:
            print(f"ctsim: figures skipped after the signal; `ctsim report {out}` draws them", file=sys.stderr)
        elif report and len(result):
            from sim.views.figures import report_run_dir

            if stop is not None:
                stop.phase = "draw"
            try:
                written += report_run_dir(out)
            except KeyboardInterrupt:
                print(f"ctsim: figures stopped by the signal; `ctsim report {out}` draws them", file=sys.stderr)
        from sim.web.report import write_run_report

        written.append(write_run_report(out))
    except OSError as err:
        kept = ", ".join(p.name for p in written[1:]) or "nothing"
        print(f"ctsim: error: writing the run's results into {out}: {err.strerror or err} (written: {kept})", file=sys.stderr)
        return EXIT_FAILED
    print(table(summary))
    for note in getattr(result, "notes", ()):  # what the run's guards put back (`sim.guards`)
        print(f"ctsim: note: {note}", file=sys.stderr)
    for log in result.robots:  # what a general chassis did other than asked (projected twists)
        for message, count in log.notes.values():
            print(f"ctsim: note: {log.name}: {message} ({count} step{'s' if count != 1 else ''} like it)", file=sys.stderr)
    print("wrote:")
    for path in written:
        print(f"  {path}")
    if recording_error is not None:
        print(f"ctsim: error: the recording is incomplete: {recording_error}", file=sys.stderr)
        return EXIT_FAILED
    if result.reason == Ending.ERROR:
        print(f"ctsim: run stopped: {sanitize.name(result.error, 2000)}", file=sys.stderr)
        return EXIT_FAILED
    if isinstance(result.reason, Ending) and result.reason.signalled:
        print(f"ctsim: {result.error}; partial results written to {out}", file=sys.stderr)
        return EXIT_INTERRUPTED if result.reason is Ending.INTERRUPTED else EXIT_TERMINATED
    return (stop.status() if stop is not None else None) or 0


def write_trajectories(result, out: Path, summary: dict[str, Any], export_rate: float | None = None) -> list[Path]:
    """run.parquet (every sample: poses and readings), truth.tum and <estimate>.tum (prefixed with
    the robot name when there are several) and the same as CSV, at `export_rate` samples per second
    (None: all); records the file names in the summary for `ctsim report`."""
    from sim.analysis.export import write_parquet, write_run

    every = max(1, round(1 / (export_rate * result.dt))) if export_rate else 1
    written = [write_parquet(result, out / "run.parquet")]
    summary["parquet"], summary["export_every"] = written[0].name, every
    tums = write_run(result, out, prefix=len(result.robots) > 1, with_csv=True, every=every)
    for entry in summary["robots"]:
        entry["tum"] = {label: path.name for label, path in tums[entry["name"]].items()}
        written += [path for tum in tums[entry["name"]].values() for path in (tum, tum.with_suffix(".csv"))]
    return written


def _nees(errors: dict[str, Any]) -> str:
    """An estimate's mean NEES for the table ('-' without a covariance; 3 is consistent)."""
    value = errors.get("nees_mean")
    return "-" if value is None or not math.isfinite(value) else f"{value:.1f}"


def table(summary: dict[str, Any]) -> str:
    """The short end-of-run table: per robot distance and collisions, per estimate its errors."""
    reached = [sanitize.name(robot["name"], 40) for robot in summary["robots"] if robot["goal_time"] is not None]
    outcome = {
        Ending.GOAL: f"goal reached by {', '.join(reached)}", Ending.DURATION: "time limit reached",
        Ending.DONE: "done (every controller said it is done)", Ending.QUIT: "quit (window closed)",
    }.get(summary["reason"], summary["reason"])  # fmt: skip
    if summary["reason"] == Ending.DURATION and reached:
        outcome = f"goal reached by {', '.join(reached)}, ran on to the time limit"
    lines = [
        f"{sanitize.name(summary['world']['name'])}, seed {summary['seed']}, noise {summary.get('noise', 'none')}, "
        f"{summary['time']:.2f} s simulated: {outcome}"
    ]
    header = f"{'robot':<12}{'estimate':<12}{'distance m':>11}{'collisions':>11}{'final err m':>12}{'ATE RMS m':>11}{'final hdg °':>12}{'NEES':>7}"
    lines.append(header)
    for robot in summary["robots"]:
        first = f"{sanitize.name(robot['name'], 40):<12}{'':<12}{robot['distance']:>11.3f}{robot['collisions']:>11d}"
        notes = [note for note in ("fell into a hole" if robot["fell"] else "", f"goal at {robot['goal_time']:.2f} s" if robot["goal_time"] is not None else "",
                                   f"controller: {robot['status']}" if robot.get("status") not in (None, "running") else "") if note]  # fmt: skip
        lines.append(first + ("   " + ", ".join(notes) if notes else ""))
        for name, errors in robot["estimates"].items():
            lines.append(f"{'':<12}{name:<12}{'':>11}{'':>11}{errors['final_position_error']:>12.4f}{errors['ate_rmse']:>11.4f}{math.degrees(errors['final_heading_error']):>12.2f}{_nees(errors):>7}")
    return "\n".join(lines)


# --- bridge -------------------------------------------------------------------------------------


def _add_bridge_parser(commands) -> None:
    from sim.bridge.usage import HOW_TO_START

    def timed(parse):
        def convert(text: str):
            from sim.bridge.usage import timed

            try:
                return timed(text, parse)
            except ValueError as err:
                raise argparse.ArgumentTypeError(str(err)) from None

        return convert

    from sim.bridge.protocol import parse_call, rc5_code

    bridge = commands.add_parser(
        "bridge",
        help="let the real c't-Bot firmware drive robots over c't-Sim's TCP protocol",
        description="Listen for c't-Bot firmwares (their PC build) as c't-Sim does and run them in lock-step with the world, "
        "10 ms per step, headless and recorded like `run` (the firmware's LCD, LEDs, motors, log and remote calls too).",
        epilog=f"{HOW_TO_START}\n\n{EXIT_STATUSES}",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    _add_robot_options(bridge)
    bridge.add_argument("--robots", type=_whole, default=1, metavar="N", help="number of firmware bots (default: 1)")
    bridge.add_argument("--controller", action="append", metavar="NAME|FILE.py[:NAME]", help="also add a robot with this Python controller (repeatable)")
    bridge.add_argument("--param", action="append", type=_param, default=[], metavar="KEY=VALUE", help="parameter of the Python controllers")
    bridge.add_argument("--duration", type=_positive(float, MAX_DURATION, "s"), default=60.0, metavar="SECONDS", help="simulated time to run (default: 60)")
    bridge.add_argument("--host", default="127.0.0.1", help="address to listen on (default: 127.0.0.1, this machine only)")
    bridge.add_argument("--port", type=_whole, default=10001, help="TCP port (default: 10001, the firmware's fixed port)")
    bridge.add_argument("--connect-timeout", type=_positive(float, MAX_STEP_TIMEOUT, "s"), default=60.0, metavar="SECONDS", help="wait this long for each firmware to connect (default: 60)")
    bridge.add_argument("--step-timeout", type=_positive(float, MAX_STEP_TIMEOUT, "s"), default=10.0, metavar="SECONDS",
                        help="a firmware silent this long in one step has hung (default: 10, c't-Sim's)")
    bridge.add_argument("--realtime", action="store_true", help="run at c't-Sim's real time (100 steps/s) instead of as fast as the firmware answers")
    bridge.add_argument("--rc5", action="append", type=timed(rc5_code), default=[], metavar="T:KEY",
                        help="press an RC5 key at T s: 0-9, PWR, UP, DOWN, LEFT, RIGHT, PLAY, CH+, CH-, VOL+, VOL-, I/II or a code (repeatable)")
    bridge.add_argument("--call", action="append", type=timed(parse_call), default=[], metavar="T:'CALL'", help="remote call at T s, e.g. 2:'bot_turn(90)' (repeatable)")
    bridge.add_argument("--list-calls", action="store_true", help="ask each firmware for the remote calls it offers and print them (c't-Sim's RemoteCallViewer)")
    bridge.add_argument("--own-physics", action="store_true",
                        help="firmware bots meet walls (slide), see them (nearest point in the IR cone), read lines at one point "
                        "and meet lamp pillars as whole wall cells, with ctsim's own models instead of c't-Sim's")
    bridge.set_defaults(handler=cmd_bridge)


def cmd_bridge(args: argparse.Namespace) -> int:
    from sim.bridge import Bridge
    from sim.run.loop import run
    from sim.views.recording.arrow import keep_pandas_out_of_arrow
    from sim.views.recording.recorder import Recorder
    from sim.world.files import load_world

    step_count(args.duration, args.dt)
    world = load_world(args.world, pillars="cell" if args.own_physics else "cylinder")
    spec = load_robot_spec(args)
    if args.robots < 1:
        raise UsageError(f"--robots must be at least 1, got {args.robots}")
    room = len(world.start_order())
    python = _setups(args, spec, room) if args.controller else []
    if args.robots + len(python) > room:
        raise UsageError(f"{args.robots} firmware bot(s) and {len(python)} Python robot(s), but the world has room for {room} "
                         "(one start slot each); add starts (slot 1, 2, ...) to the world")
    out = _out_dir(args.out, args.world, "bridge")
    calls = [(at, f"{name}({', '.join(map(str, params))})") for at, (name, params) in args.call]
    with Bridge(args.host, args.port, args.connect_timeout, args.step_timeout, dt=args.dt, list_calls=args.list_calls) as bridge:
        setups = [bridge.setup(spec, rc5=args.rc5, calls=calls, like_ctsim=not args.own_physics) for _ in range(args.robots)] + python
        print(f"ctsim bridge: listening on {bridge.address} for {args.robots} firmware bot(s); start the firmware now", file=sys.stderr, flush=True)
        keep_pandas_out_of_arrow()
        recorder = Recorder(out / "run.rrd", live=args.live)
        with StopOnSignal() as stop:
            observers = (stop.starting, bridge.observer(recorder, realtime=args.realtime), recorder, Progress(args.duration, args.dt), stop)
            result = run(world, setups, args.duration, dt=args.dt, seed=args.seed, observers=observers)
        for bot in bridge.summary():
            if args.list_calls:
                print(f"{bot['label']} offers {len(bot['functions'])} remote calls:" + "".join(f"\n  {f}" for f in bot["functions"]))
            for call in bot["calls"]:
                outcome = f"result {call['result']} at step {call['done_step']}" if call["result"] is not None else "no result (r/D) yet"
                print(f"{bot['label']}: {call['call']} sent at step {call['sent_step']}: {outcome}")
        # the firmwares are shut down when the files are written (leaving the `with`)
        return finish(result, out, {"duration": args.duration, "until_goal": False, **_robot_options(args), "bridge": bridge.summary()}, report=not args.no_report, export_rate=args.export_rate)
# --- sweep ------------------------------------------------------------------------------------


def _add_sweep_parser(commands) -> None:  # noqa: ANN001 (argparse's subparsers action)
    sweep = commands.add_parser(
        "sweep",
        help="run many runs from a TOML spec (grid or random), resumable; `sweep report DIR` draws its figures",
        description="Run every run a sweep spec plans (see README, 'Sweeps') on local processes (default, all cores) or Dask, "
        "one Parquet row per run in DIR/results.parquet, kept as runs finish: run it again to finish an interrupted sweep. "
        "`ctsim sweep report DIR` draws the figures of a sweep folder.",
    )
    sweep.add_argument("spec", metavar="SPEC.toml|report", help="the sweep spec, or `report` followed by a sweep folder")
    sweep.add_argument("folder", nargs="?", type=Path, metavar="DIR", help="(with report) the sweep folder")
    sweep.add_argument("--out", type=Path, metavar="DIR", help="sweep folder (default: runs/sweep-<spec name>)")
    sweep.add_argument("--engine", choices=("processes", "dask", "serial"), default="processes", help="local processes (default), a Dask LocalCluster, or one run after another here")
    sweep.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="run on the Dask cluster whose scheduler is there (implies --engine dask)")
    sweep.add_argument("--jobs", type=_whole, metavar="N", help="worker processes (default: one per core)")
    sweep.add_argument("--by", action="append", metavar="SETTING",
                       help="group the summary and figures by this setting, repeatable (default: every swept one but seed); the others are pooled, and each table and figure says so")
    sweep.set_defaults(handler=cmd_sweep)


def cmd_sweep(args: argparse.Namespace) -> int:
    from sim.experiments import engine, load_results, load_sweep, sweep
    from sim.experiments.report import grouping, pooled_note, summary_table, terminal_table

    def show(table) -> None:  # noqa: ANN001 (a DataFrame)
        by, pooled = grouping(table, args.by)
        print(f"per {', '.join(by) or 'sweep'}; {pooled_note(table, pooled)}:")
        print(terminal_table(summary_table(table, by)))

    if args.spec == "report":
        from sim.web.report import write_sweep_report

        if args.folder is None or not args.folder.is_dir():
            raise UsageError(f"sweep report needs a sweep folder, got {args.folder}")
        paths = write_sweep_report(args.folder, by=args.by)
        show(load_results(args.folder))
        for path in paths:
            print(path)
        return 0
    if args.folder is not None:
        raise UsageError(f"unexpected argument {str(args.folder)!r} (the folder goes in --out)")
    if args.jobs is not None and args.jobs < 1:
        raise UsageError(f"--jobs must be at least 1, got {args.jobs}")
    spec = load_sweep(args.spec)
    out = args.out or Path("runs") / f"sweep-{Path(args.spec).stem}"
    runner = engine(args.engine, args.jobs, args.scheduler)
    try:
        table = sweep(spec, out, runner)
    finally:
        runner.close()
    failed = int((table["reason"] == Ending.ERROR).sum())
    show(table)
    print(f"{len(table)} runs, {failed} failed (see the error column); table: {out / 'results.parquet'}")
    return 0


# --- listings ---------------------------------------------------------------------------------


def cmd_report(args: argparse.Namespace) -> int:
    from sim.views.figures import report_run_dir

    if not (args.run_dir / "summary.json").is_file():
        raise UsageError(f"{args.run_dir}: not a run folder (no summary.json)")
    from sim.web.report import write_run_report

    for path in [*report_run_dir(args.run_dir), write_run_report(args.run_dir)]:
        print(path)
    return 0


def first_sentence(text: str) -> str:
    """The first sentence of a text: up to a full stop followed by a capital (so that "e.g. a"
    and "0.24 m" do not end it), whitespace folded."""
    return re.split(r"(?<=[.!?])\s+(?=[A-Z])", " ".join(text.split()), maxsplit=1)[0]


def cmd_worlds(args: argparse.Namespace) -> int:
    import textwrap

    from sim.world.files import load_world, shipped_worlds

    for name, path in shipped_worlds().items():
        world = load_world(path)
        xmin, ymin, xmax, ymax = world.bounds
        first = first_sentence(world.description).rstrip(".")  # it says what the world is for
        room = len(world.start_order())
        lead = f"{name:<14}{xmax - xmin:5.2f} x {ymax - ymin:<5.2f} m  "
        print(textwrap.fill(f"{first} ({room} start{'s' if room != 1 else ''})", width=100, initial_indent=lead, subsequent_indent=" " * len(lead)))
    return 0


def cmd_check(args: argparse.Namespace) -> int:
    from sim.world.files import load_world, room_warning, world_warnings

    world = load_world(args.world)
    warnings = [w for w in (*world_warnings(world), room_warning(world)) if w]
    xmin, ymin, xmax, ymax = world.bounds
    counts = ", ".join(f"{len(getattr(world, k))} {k}" for k in ("walls", "floor", "lines", "holes", "lights", "starts", "goals", "movables"))
    for warning in warnings:
        print(f"{args.world}: warning: {warning}")
    room = len(world.start_order())
    print(f"OK {args.world}: {sanitize.name(world.name)}, {xmax - xmin:.2f} x {ymax - ymin:.2f} m; {counts}; room for {room} robot(s)")
    return 0


def cmd_controllers(args: argparse.Namespace) -> int:
    import inspect
    import textwrap

    import bots.behaviours  # noqa: F401  (registers the shipped controllers)
    from bots.controller import REGISTRY, parameters


    if not REGISTRY:
        print("no controllers registered")
    for name in sorted(REGISTRY):
        factory = REGISTRY[name]
        shown = [p.name if p.default is inspect.Parameter.empty else f"{p.name}={p.default!r}" for p in parameters(factory).values()]
        doc = " ".join((inspect.getdoc(factory) or "").split("\n\n")[0].split())
        print(textwrap.fill(doc, width=100, initial_indent=f"{name:<16}", subsequent_indent=" " * 16))
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
    previous = signal.signal(signal.SIGTERM, _terminate)
    if sys.stderr.isatty():  # someone waits at a terminal: say why the first run takes a while
        compiling.PROGRESS = lambda line: print(f"ctsim: {line}", file=sys.stderr, flush=True)
    try:
        return args.handler(args)
    except BrokenPipeError:  # `ctsim controllers | head`: the reader has all it wanted
        sys.stdout = None
        return 0
    except UserError as err:
        print(f"ctsim: error: {sanitize.name(str(err), 2000)}", file=sys.stderr)
        return EXIT_USER
    except OSError as err:
        if not _names_user_path(err, args):
            return _bug()
        where = f"{err.filename}: " if err.filename else ""  # no errno, no repr
        print(f"ctsim: error: {where}{err.strerror or err}", file=sys.stderr)
        return EXIT_USER
    except KeyboardInterrupt as stop:  # outside a run (a run keeps its results and ends normally)
        terminated = isinstance(stop, Terminated)
        print(f"ctsim: {'terminated' if terminated else 'interrupted'}", file=sys.stderr)
        return EXIT_TERMINATED if terminated else EXIT_INTERRUPTED
    except Exception:
        return _bug()
    finally:
        signal.signal(signal.SIGTERM, previous)
        while _held:
            _held.pop().close()


def _names_user_path(err: OSError, args: argparse.Namespace) -> bool:
    """Whether the failed file is one the command line named (an argument or an option), lies
    inside one, or is a folder on the way to one: the user's to fix (exit 2), not ctsim's bug."""
    failed = [Path(os.fsdecode(name)).absolute() for name in (err.filename, err.filename2) if name not in (None, "")]
    named = []
    for value in vars(args).values():
        for item in value if isinstance(value, list) else [value]:
            if isinstance(item, str | Path) and str(item).strip():
                named.append(Path(str(item).partition(".py:")[0]).absolute())  # FILE.py:Class names FILE.py
    return any(path == given or given in path.parents or path in given.parents for path in failed for given in named)


def _bug() -> int:
    """The traceback of an exception that is no user mistake, and what to do about it: exit 1."""
    traceback.print_exc()
    print(f"ctsim: error: this is a bug in ctsim {sim.__version__}, not a mistake of yours: please report it "
          "with the command you ran and the traceback above", file=sys.stderr)
    return EXIT_FAILED


if __name__ == "__main__":
    sys.exit(main())
