"""The Python API, as small as the command line: a world, robots with controllers, a run, a result.

    from sim.experiments import Bot, simulate
    result = simulate("maze", Bot("solve_maze"), duration=10, seed=1)
    result.robots[0].truth              # (T, 3) ground-truth poses (x, y m; heading rad)
    result.robots[0].estimates["mouse"] # (T, 3) what the mouse odometry believed
    result.metrics_frame()              # pandas: one row per robot and estimator

Everything here is a thin layer over `sim.run.loop.run`; `ctsim run` calls `simulate` too.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import asdict, dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from bots.controller import Controller, FunctionController
from bots.noise import DEFAULT_NOISE
from bots.spec import RobotSpec
from sim.analysis.metrics import compare_run, path_lengths
from sim.errors import UserError
from sim.guards import making
from sim.run.clock import made_in_time
from sim.run.ending import Ending
from sim.run.loop import RobotSetup, check_seed, run
from sim.run.samples import RobotLog, RunResult
from sim.world.spec import Start, WorldSpec
from sim.world.step import DEFAULT_DT, check_dt


def world(source: str | Path | WorldSpec) -> WorldSpec:
    """A world: a shipped world's name (`"maze"`), a `.toml`/`.xml` file, or a WorldSpec as is."""
    if isinstance(source, WorldSpec):
        return source
    from sim.world.files import load_world

    return load_world(source)


def robot(source: str | Path | RobotSpec = "ctbot", changes: dict[str, Any] | None = None, noise: str = DEFAULT_NOISE) -> RobotSpec:
    """A robot description: a built-in name (`"ctbot"`, a wheeled chassis), a TOML robot file or a
    RobotSpec, with a `noise` preset ("realistic" by default, "none", "harsh": `bots.noise`, as
    `--noise`) and then `changes` by dotted field name applied (see `change_robot`; as `--robot-set`)."""
    from bots.noise import with_noise

    if isinstance(source, RobotSpec):
        spec = source
    else:
        from bots.ctbot import ROBOTS
        from bots.spec import load_robot
        from bots.wheeled import WHEELED_ROBOTS

        ROBOTS = {**ROBOTS, **WHEELED_ROBOTS}
        if str(source) in ROBOTS:
            spec = ROBOTS[str(source)]
        elif str(source).endswith(".toml") or Path(source).exists():
            spec = load_robot(source)
        else:
            raise UserError(f"unknown robot {str(source)!r} (built-in: {', '.join(ROBOTS)}; or a .toml file)")
    return change_robot(with_noise(spec, noise), changes or {})


def change_robot(spec: RobotSpec, changes: dict[str, Any]) -> RobotSpec:
    """A copy of `spec` with fields replaced by dotted name: `{"encoders.slip_std": 0.02,
    "mouse.noise_std": 0.5, "ir.noise_std": 0.01, "wheel_diameter": 0.057}`. A name under a
    sensor group (`ir`, `line`, `border`, `light`) changes every sensor of the group; lists
    become tuples (`"encoders.diameter_error": [0.01, -0.01]`). The same as `--robot-set`
    (`bots.noise.with_settings`): a name that is no field, or a value its field refuses, is a
    RobotSettingError naming it."""
    from bots.noise import with_settings

    return with_settings(spec, changes)


@dataclass
class Bot:
    """A robot to put in a world. `controller`: a registered name, `"file.py[:Name]"`, a controller
    object (anything with `step(t, readings)`) or a function `f(t, readings) -> Command`.
    `params`: the controller's parameters (for names and files). `robot`: as `robot()` takes it,
    with its `noise` preset (None: the one `simulate` is given) and `changes` by dotted field
    name. `start`: (x, y m, heading rad); None: the world's next start slot."""

    controller: str | Controller | Callable = "solve_maze"
    params: dict[str, Any] = field(default_factory=dict)
    robot: str | Path | RobotSpec = "ctbot"
    changes: dict[str, Any] = field(default_factory=dict)
    start: Start | tuple[float, float, float] | None = None
    noise: str | None = None

    def setup(self, noise: str = DEFAULT_NOISE) -> RobotSetup:
        """The run loop's description of this robot (controllers by name are built here);
        `noise`: the preset unless the Bot names its own.

        >>> setup = Bot("wander", noise="harsh").setup(noise="none")
        >>> setup.controller_name, setup.spec.name, Bot("wander", noise="harsh").noise_of("none")
        ('wander', 'ctbot', 'harsh')
        """
        spec = robot(self.robot, self.changes, self.noise_of(noise))
        params = {k: _text(v) for k, v in self.params.items()}
        if isinstance(self.controller, str):
            from bots.behaviours import make

            return RobotSetup(spec, make(self.controller, params), self.controller, params, self.start)
        made = self.controller if hasattr(self.controller, "step") else FunctionController(self.controller)
        name = getattr(made, "name", type(made).__name__)
        return RobotSetup(spec, made, name, params, self.start)


    def noise_of(self, noise: str = DEFAULT_NOISE) -> str:
        """The noise preset this Bot runs with where `simulate` is given `noise`."""
        return self.noise or noise


def _text(value: Any) -> str:
    """A parameter as the command line would spell it (controllers convert by annotation)."""
    return str(value).lower() if isinstance(value, bool) else str(value)


@dataclass
class RobotResult:
    """One robot's run: trajectories as numpy arrays and odometry metrics per estimator;
    `covariances` the (T, 6) covariance entries (`bots.uncertainty.COVARIANCE_FIELDS`) of the
    estimates that have one. The arrays are read from the run's file when first asked for (the
    caller's own copies): a run that only wants its metrics (`ctsim run`, sweeps) never holds a
    long run's trajectories in memory."""

    name: str
    controller: str
    metrics: dict[str, dict[str, float]]
    collisions: int
    fell: bool
    goal_time: float | None
    log: RobotLog = field(repr=False, compare=False)
    """The run loop's log of the robot, which the arrays are read from."""

    @cached_property
    def truth(self) -> np.ndarray:
        """(T, 3) ground-truth poses."""
        return np.array(self.log.truth_array())

    @cached_property
    def estimates(self) -> dict[str, np.ndarray]:
        """Estimator name -> (T, 3) estimated poses."""
        return {label: np.array(poses) for label, poses in self.log.estimate_arrays().items()}

    @cached_property
    def covariances(self) -> dict[str, np.ndarray]:
        """Estimator name -> (T, 6) covariance entries of the estimates that have one."""
        return {label: np.array(entries) for label, entries in self.log.covariance_arrays().items()}

    @property
    def distance(self) -> float:
        """Metres the robot really drove."""
        return float(path_lengths(self.truth)[-1]) if len(self.truth) else 0.0

    def __getstate__(self) -> dict:
        """Pickled with its arrays read and without the log (whose samples live in an open file),
        so that a result crosses to another process (multiprocessing, joblib) as it did."""
        state = dict(self.__dict__)
        for name in ("truth", "estimates", "covariances"):
            state[name] = getattr(self, name)
        state["log"] = None
        return state


@dataclass
class Result:
    """A finished run. `reason`: as `sim.run.samples.RunResult.reason` (an `Ending`, a str: 'duration', 'goal', 'done', 'error',
    ...); `error`: the one-line message of a failure; `raw`: the run loop's own result (for
    `ctsim run`'s files); `time` the (T,) sample times (s), read when first asked for."""

    robots: list[RobotResult]
    reason: Ending
    error: str | None
    seed: int
    raw: RunResult
    recording: Path | None = None
    """The rerun recording written (`simulate(record=...)`), or None."""
    noise: str = DEFAULT_NOISE
    """The noise preset the robots ran with, or one per robot, comma-separated, where they differ
    ("as given": a RobotSetup's own robot, whose noise the API cannot name)."""

    @cached_property
    def time(self) -> np.ndarray:
        """(T,) sample times (s)."""
        return np.array(self.raw.time)

    def summary(self) -> dict[str, Any]:
        """The run as summary.json describes one (`sim.analysis.summary`: world, seed, dt, time,
        reason, per robot its distance, collisions and each estimate's metrics)."""
        from sim.analysis.summary import summarize

        return summarize(self.raw, {"noise": self.noise}, {r.name: r.metrics for r in self.robots})

    def _repr_html_(self) -> str:
        """Jupyter shows a result as its summary table, its figures and the run's facts."""
        from sim.views.html import run_fragment

        tracks = {r.name: {"truth": (self.time, r.truth), **{label: (self.time, poses) for label, poses in r.estimates.items()}} for r in self.robots}
        return run_fragment(self.raw.world, self.summary(), tracks)

    def metrics_frame(self) -> Any:
        """pandas DataFrame, one row per robot and estimator, one column per metric."""
        import pandas as pd

        rows = [{"robot": r.name, "estimator": est, **values} for r in self.robots for est, values in r.metrics.items()]
        return pd.DataFrame(rows)


def result_of(raw: RunResult) -> Result:
    """The API's view of a run loop result."""
    metrics = compare_run(raw) if len(raw) else {}
    robots = [
        RobotResult(
            name=log.name,
            controller=log.controller_name,
            metrics={est: asdict(m) for est, m in metrics.get(log.name, {}).items()},
            collisions=log.collisions,
            fell=log.fell,
            goal_time=log.goal_time,
            log=log,
        )
        for log in raw.robots
    ]
    return Result(robots, raw.reason, raw.error, raw.seed, raw)


def with_estimators(setups: list[RobotSetup], estimators: Iterable[Any]) -> list[RobotSetup]:
    """`setups` with a fresh one of each of `estimators` (as `simulate` takes them) beside the
    defaults of every robot without estimators of its own; made here, so a constructor that
    fails does before anything runs (`bots.odometry.user.made`)."""
    extra = list(estimators)
    if not extra:
        return setups
    from bots.odometry.user import beside_defaults

    return [replace(s, extra_estimators=beside_defaults(s.spec, extra)) if s.estimators is None else s for s in setups]


def simulate(
    world_source: str | Path | WorldSpec = "maze",
    *bots: Bot | RobotSetup | Iterable[Bot | RobotSetup],
    robots: Iterable[Bot | RobotSetup] = (),
    noise: str = DEFAULT_NOISE,
    duration: float = 60.0,
    dt: float = DEFAULT_DT,
    seed: int = 0,
    until_goal: bool = False,
    record: str | Path | None = None,
    live: bool = False,
    observers: Iterable = (),
    step_timeout: float | None = None,
    estimators: Iterable[Any] = (),
) -> Result:
    """Run `bots` and `robots` (Bots or lists of them; default: one c't-Bot solving the maze) in a
    world for `duration` seconds of simulated time, or until one reaches a goal, every Bot with
    the `noise` preset (`bots.noise.DEFAULT_NOISE`, realistic, as `ctsim run`) unless it names its own; `record` writes a rerun recording there; a
    controller step longer than `step_timeout` seconds (wall clock) ends the run as its error.
    `estimators`: your own (classes, factories, estimator objects or "FILE.py:Class", as
    `bots.odometry.user.made` takes them): every robot without estimators of its own gets a fresh
    one of each beside its defaults, in every output; one that fails a step ends the run as a
    controller's error does.
    `ctsim run` is this call: `--robots 3` is `robots=[Bot()] * 3`.

    >>> result = simulate("empty", Bot("idle"), duration=0.1)
    >>> str(result.reason), len(result.time), result.robots[0].truth.shape
    ('duration', 11, (11, 3))
    """
    check_dt(dt)
    check_seed(seed)  # (before any controller is made)
    spec = world(world_source)
    given = [b for item in (*bots, *robots) for b in (item if isinstance(item, list | tuple) else (item,))]
    for b in given:
        if not isinstance(b, Bot | RobotSetup):
            raise TypeError(f"simulate: a robot is a Bot or a RobotSetup, got {type(b).__name__}: {b!r}")
    given = given or [Bot()]
    with making() as replaced, made_in_time(step_timeout):  # (what a constructor replaces in ctsim is put back before the run: `sim.guards`)
        setups = [b.setup(noise) if isinstance(b, Bot) else b for b in given]
        setups = with_estimators(setups, estimators)
    noises = [b.noise_of(noise) if isinstance(b, Bot) else "as given" for b in given]
    watchers = list(observers)
    if record is not None or live:
        from sim.views.recording.recorder import Recorder

        watchers.insert(0, Recorder(record, live=live))
    raw = run(spec, setups, duration, dt=dt, seed=seed, until_goal=until_goal, observers=tuple(watchers), step_timeout=step_timeout)
    raw.notes[:0] = replaced
    named = noises[0] if len(set(noises)) == 1 else ", ".join(noises)
    return replace(result_of(raw), recording=Path(record) if record is not None else None, noise=named)
