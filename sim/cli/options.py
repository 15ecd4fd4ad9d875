"""What the commands share: exit statuses, the parser that refuses in one line, option types checked
as a file's values are, the robot options and the robots they set up."""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from bots.noise import DEFAULT_NOISE, NOISE_PRESETS, parse_value
from bots.schema import Field, option, parse_number, shown
from sim.errors import UserError
from sim.world.step import DEFAULT_DT, DT_RANGE, StepError, check_dt

DEFAULT_WORLD = "maze"
DEFAULT_CONTROLLER = "solve_maze"
EXIT_FAILED, EXIT_USER, EXIT_INTERRUPTED, EXIT_TERMINATED = 1, 2, 130, 143
EXIT_STATUSES = f"""exit status:
  0    success
  {EXIT_FAILED}    a run that started failed (a controller or estimator raised, KeyboardInterrupt too,
       called sys.exit or os._exit, returned a bad command or overran --step-timeout, in its reset or
       a step; or the disk filled up; `evaluate`: any of its runs);
       what was recorded up to then is written; or your controller's or estimator's constructor
       failed (one line); or ctsim has a bug: its traceback and a request to report it are printed
  {EXIT_USER}    a user error found before anything ran (bad option, world, robot or controller)
  {EXIT_INTERRUPTED}  interrupted by Ctrl-C; partial results written
  {EXIT_TERMINATED}  terminated by SIGTERM (a job scheduler, `timeout`); partial results written"""


class UsageError(UserError):
    """A user mistake found by the CLI itself."""


class Parser(argparse.ArgumentParser):
    """Bad options get one line, like every other user error (argparse prints the usage too);
    every --help ends with the exit statuses."""

    def __init__(self, *args: Any, **kwargs: Any):
        kwargs.setdefault("epilog", EXIT_STATUSES)
        kwargs.setdefault("formatter_class", argparse.RawDescriptionHelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str):
        self.exit(EXIT_USER, f"ctsim: error: {message} (see `{self.prog} --help`)\n")


def param(text: str) -> tuple[str, str]:
    key, sep, value = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=VALUE, got {shown(text)}")
    try:
        parse_value(value.strip())  # (a number of thousands of digits is refused here, naming the option)
    except ValueError as err:
        raise argparse.ArgumentTypeError(f"{key.strip()}: {err}") from None
    return key.strip(), value.strip()


def whole(text: str) -> int:
    """A whole-number option (at most `bots.schema.MAX_DIGITS` digits)."""
    try:
        return int(parse_number(text, int))
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def seed(text: str) -> int:
    value = whole(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a seed of 0 or more, got {value}")
    return value


def positive(kind: Callable[[str], Any], high: float = 1e9, unit: str = "", low: float = 0.0) -> Callable[[str], Any]:
    """A positive option of `kind` (float or int) up to `high` (and at least `low`, if given),
    checked as a file's value is (`bots.schema.option`: NaN, infinities, subnormals and 40+ digit
    numbers refused)."""
    checked = option(Field("integer" if kind is int else "number", unit, low, high, above=not low), kind)

    def parse(text: str) -> Any:
        try:
            value = parse_number(text, kind)
        except ValueError as err:
            raise argparse.ArgumentTypeError(str(err)) from None
        if not value > 0:
            raise argparse.ArgumentTypeError(f"expected a positive number, got {shown(text)}")
        return checked(text)

    return parse


def step_size(text: str) -> float:
    value = positive(float)(text)
    try:
        check_dt(value)
    except StepError:
        raise argparse.ArgumentTypeError(f"expected a step between {DT_RANGE[0]:g} and {DT_RANGE[1]:g} s, got {text!r}") from None
    return value


def folder_name(text: str) -> Path:
    if not text.strip():
        raise argparse.ArgumentTypeError("expected a folder, got an empty name")
    return Path(text)


NOISE_HELP = {
    "realistic": "sensor and odometry noise of the robot: realistic (the c't-Bot's figures and their sources, see bots/noise.py), harsh, "
    "or none (exact sensors, for checks against closed forms) (default: realistic)",
    "none": "sensor and odometry noise of the robots: none (exact, as in c't-Sim, whose wheels and sensors have no noise: the firmware "
    "takes c't-Sim's path), realistic (the c't-Bot's figures, see bots/noise.py) or harsh (default: none)",
}
"""--noise's help by the command's default: every command is realistic (`bots.noise.DEFAULT_NOISE`) unless it stands in for c't-Sim (`bridge`)."""


def add_noise_option(parser: argparse.ArgumentParser, default: str = DEFAULT_NOISE) -> None:
    """--noise: a preset of `bots.noise`, by default the one of every way of starting a run."""
    parser.add_argument("--noise", choices=NOISE_PRESETS, default=default, help=NOISE_HELP[default])


def add_robot_options(parser: argparse.ArgumentParser, noise: str = DEFAULT_NOISE) -> None:
    parser.add_argument("world", nargs="?", default=DEFAULT_WORLD, help=f"a shipped world's name (see `ctsim worlds`) or a .toml/.xml world file (default: {DEFAULT_WORLD})")
    add_robot_description(parser, noise)
    parser.add_argument("--out", type=folder_name, metavar="DIR", help="folder for run.rrd, summary.json, TUM/CSV trajectories and figures (default: runs/<world>-<controller>-<time>)")
    parser.add_argument("--live", action="store_true", help="also stream the recording to a rerun viewer it starts; without one the run goes on, recorded to the file")
    parser.add_argument("--connect", metavar="URL", help="also stream the recording to the rerun viewer at URL (e.g. rerun+http://127.0.0.1:9876/proxy)")
    parser.add_argument("--no-report", action="store_true", help="skip the PNG figures")
    parser.add_argument("--export-rate", type=positive(float, 1e6, "Hz"), metavar="HZ",
                        help="samples per second in the TUM and CSV files (default: every step; run.parquet always holds every sample)")


def add_robot_description(parser: argparse.ArgumentParser, noise: str = DEFAULT_NOISE) -> None:
    """--robot, --seed, --noise, --robot-set and --dt: the robot and how it is simulated (`load_robot_spec`)."""
    parser.add_argument("--robot", default="ctbot", metavar="NAME|FILE.toml",
                        help="robot description: a built-in name (ctbot, omni3, mecanum4, car, ocp_vehicle) or a TOML robot file (default: ctbot)")
    parser.add_argument("--seed", type=seed, default=0, help="seed of every random number in the run (the noise of --noise realistic or harsh); same seed, same run (default: 0)")
    add_noise_option(parser, noise)
    parser.add_argument("--robot-set", action="append", type=param, default=[], metavar="SECTION.FIELD=VALUE",
                        help="override one field of the robot description after --noise, repeatable: encoders.slip_std=0.02, mouse.dpi=415, ir.noise_std=0")
    parser.add_argument("--dt", type=step_size, default=DEFAULT_DT, metavar="SECONDS", help=f"simulation step (default: {DEFAULT_DT:g})")


def add_engine_options(parser: argparse.ArgumentParser) -> None:
    """Where many runs execute (`sim.experiments.engines`): `ctsim sweep` and `ctsim evaluate`."""
    parser.add_argument("--engine", choices=("processes", "dask", "serial"), default="processes", help="local processes (default), a Dask LocalCluster, or one run after another here")
    parser.add_argument("--scheduler", metavar="tcp://HOST:PORT", help="run on the Dask cluster whose scheduler is there (implies --engine dask)")
    parser.add_argument("--jobs", type=whole, metavar="N", help="worker processes (default: one per core)")


def engine_of(args: argparse.Namespace):  # noqa: ANN201 (an engine of sim.experiments.engines; imported on demand)
    """The engine the options of `add_engine_options` name."""
    from sim.experiments import engine

    if args.jobs is not None and args.jobs < 1:
        raise UsageError(f"--jobs must be at least 1, got {args.jobs}")
    most = JOBS_PER_CORE * (os.cpu_count() or 1)
    if args.jobs is not None and args.jobs > most and args.scheduler is None:
        raise UsageError(f"--jobs {args.jobs}: more worker processes than {JOBS_PER_CORE} per core ({most} here) only wait for each other and fill the memory")
    return engine(args.engine, args.jobs, args.scheduler)


JOBS_PER_CORE = 4
"""Most local worker processes per core `--jobs` starts (a Dask LocalCluster started as many as asked)."""


def add_step_timeout_option(parser: argparse.ArgumentParser, what: str) -> None:
    """--step-timeout: how long a call of the user's code may take (`sim.run.clock`), the same
    default and bounds in every command that runs it (`run`, `evaluate`)."""
    from sim.run.clock import MAX_STEP_TIMEOUT, MIN_STEP_TIMEOUT, STEP_TIMEOUT

    parser.add_argument("--step-timeout", type=positive(float, MAX_STEP_TIMEOUT, "s", MIN_STEP_TIMEOUT), default=STEP_TIMEOUT, metavar="SECONDS",
                        help=f"{what} (default: {STEP_TIMEOUT:g}; at least {MIN_STEP_TIMEOUT:g})")


def add_web_options(parser: argparse.ArgumentParser, flag: str | None = None, flag_help: str = "") -> None:
    from sim.web.serve import DEFAULT_HOST, DEFAULT_PORT

    if flag:
        parser.add_argument(flag, action="store_true", help=flag_help)
    parser.add_argument("--host", default=None, help=f"address to serve the page on (default: {DEFAULT_HOST}, this machine only; 0.0.0.0 for every network)")
    parser.add_argument("--port", type=whole, default=None, help=f"the page's port; the recording is served on the next one (default: {DEFAULT_PORT}; 0: two free ones)")


def load_robot_spec(args: argparse.Namespace):
    """The robot of --robot (a built-in name or a TOML robot file) with --noise and --robot-set,
    looked up and changed as the Python API does (`sim.experiments.api.robot`)."""
    from sim.experiments.api import robot

    return robot(args.robot, {key: parse_value(value) for key, value in args.robot_set}, args.noise)


def robot_setups(args: argparse.Namespace, spec, room: int, make: Callable[[str, dict[str, str]], Any] | None = None) -> list:
    """One RobotSetup per robot from --controller/--robots/--param; the world has start slots for
    `room` robots (one slot each). `make(name, params)`: the controller (default: made here)."""
    if make is None:
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


def robot_options(args: argparse.Namespace) -> dict[str, Any]:
    """The robot options of a run for its summary."""
    return {"robot": args.robot, "noise": args.noise, "robot_set": {key: parse_value(value) for key, value in args.robot_set}}
