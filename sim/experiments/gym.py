"""Gymnasium environments: a c't-Bot learning a task from its own sensor readings.

    import gymnasium as gym
    import sim.experiments.gym  # registers ctsim/MazeNav-v0 and ctsim/LineFollow-v0
    env = gym.make("ctsim/LineFollow-v0", render_mode="rgb_array")
    envs = gym.make_vec("ctsim/LineFollow-v0", num_envs=64)    # CtsimVectorEnv: one world, one batch
    envs = gym.make_vec("ctsim/LineFollow-v0", num_envs=8, vectorization_mode="async")  # a process each

**Observation** (float32 Box, in this order): each IR sensor's distance (m, 0 .. its far limit;
nothing in range reads the far limit), each line then border sensor (0 white .. 1 black or a
hole), each light sensor (0 bright .. 1 dark), the two wheels' rim speeds the encoders measured
over the last control step (m/s, left then right); the maze task adds the goal as the robot sees
it: its distance (m) and the cosine and sine of its bearing from the robot's heading.
**Action** (float32 Box [-1, 1]^2; anything else, NaN included, is refused with a ValueError): wheel rim speeds as fractions of the top rim speed
(`action="wheels"`, left then right), or a twist (`action="twist"`): forward speed as a fraction of
the top rim speed and turn rate as a fraction of the top turn rate (2 x top rim speed / track).
One env step is `control_dt` seconds (default 0.05 s: five physics steps of `dt`); the sensors
are read once per env step, at its end.

**Tasks and rewards** (per env step):
- `maze` (`ctsim/MazeNav-v0`): reach the goal. Reward: metres of progress towards the goal, minus
  TIME_COST per second and COLLISION_COST per new contact with a wall; GOAL_BONUS and `terminated`
  within GOAL_REACH of the goal.
- `line` (`ctsim/LineFollow-v0`): follow the floor line. Reward: metres driven forward (along the
  heading at the step's start) while a line sensor sees the line, else minus TIME_COST per second;
  minus COLLISION_COST per new contact.
Both give FALL_PENALTY and end (`terminated`) when the robot falls into a hole, and are
`truncated` after `episode_seconds` of simulated time (default 60 s: 1,200 steps, also the
registered `max_episode_steps`, which `gym.make`'s TimeLimit keeps).

**Seeds.** `reset(seed=...)` draws, from the env's generator and in this order: the start pose
(line: a point on the line, heading along it, with a little offset and turn; maze: a free point
anywhere in the maze, any heading), the goal (maze: a point in one of the world's goal areas, or
anywhere free with `goal="anywhere"`) and the seed of the robot's noise (`noise`: a preset of
`bots.noise`, realistic by default as for every run). Nothing else is random: the same seed gives
the same episode, bit for bit.
`options={"start": (x, y, heading)}` puts the robot there instead (the draws stay the same).

**Vector envs.** `CtsimVectorEnv` (the vector entry point of both ids) puts its N copies into one
world whose robots pass through each other and do not see each other (`World(robots_meet=False)`),
so that the world's compiled kernels step all of them in one call; copy i equals a CtsimEnv reset
with seed + i, step for step. For controllers that cost more than the physics, Gymnasium's
`AsyncVectorEnv` runs one CtsimEnv per process (`vectorization_mode="async"`).
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv

from bots.commands import command_per_speed
from bots.noise import DEFAULT_NOISE
from bots.readings import SensorFrame
from bots.sensor_kinds import KINDS
from bots.spec import RobotSpec
from sim.experiments.api import robot as load_robot_spec
from sim.experiments.api import world as world_spec
from sim.world import World, WorldSpec
from sim.world.layout import tally_rows
from sim.world.sensors import CNY70_MAX
from sim.world.step import DEFAULT_DT

TASKS = {"maze": "maze", "line": "line"}
"""Task name -> the shipped world it runs in by default."""
GOAL_BONUS = 10.0
FALL_PENALTY = -10.0
TIME_COST = 0.2
"""Reward lost per simulated second (per second off the line in the line task)."""
COLLISION_COST = 0.1
GOAL_REACH = 0.1
"""The maze task ends when the robot's centre is this near the goal (m)."""
OBSERVED = tuple(kind for kind in KINDS if kind.observed is not None)
"""The sensor registry's kinds an observation holds, in its order."""
LINE_SEEN = 512
"""A CNY70 value above this (0 white .. 1023 black) sees the line."""
LINE_OFFSET = 0.01
"""Line task: the start lies up to this far (m) beside the line..."""
LINE_TURN = 0.25
"""...and its heading up to this far (rad) off the line's direction."""
CLEARANCE = 0.03
"""Maze task: a drawn start or goal lies at least this far (m) beyond the robot's radius from any wall."""
DRAWS = 10_000
"""Tries to find a free point before giving up (a world with almost no free floor)."""


def observation_space(spec: RobotSpec, task: str = "line", world: WorldSpec | None = None) -> spaces.Box:
    """The Box of a robot's observations in a task (see the module docstring for the order)."""
    top = 2.0 * spec.max_wheel_surface_speed  # encoders under slip can read above the motors' limit
    low, high = [], []
    for kind in OBSERVED:
        sensors = getattr(spec, kind.section)
        low += [0.0] * len(sensors)
        high += [s.max_range for s in sensors] if kind.observed == "distance" else [1.0] * len(sensors)
    low += [-top, -top]
    high += [top, top]
    if task == "maze":
        xmin, ymin, xmax, ymax = world.bounds if world is not None else (0.0, 0.0, 100.0, 100.0)
        low += [0.0, -1.0, -1.0]
        high += [math.hypot(xmax - xmin, ymax - ymin), 1.0, 1.0]
    return spaces.Box(np.array(low, np.float32), np.array(high, np.float32), dtype=np.float32)


class _Task:
    """What every copy of an environment shares: world, robot, task, action and time settings."""

    def __init__(self, task: str, world: str | WorldSpec | None, robot: str | RobotSpec, noise: str, action: str, goal: str,
                 control_dt: float, dt: float, episode_seconds: float):  # fmt: skip
        if task not in TASKS:
            raise ValueError(f"unknown task {task!r} (tasks: {', '.join(TASKS)})")
        if action not in ("wheels", "twist"):
            raise ValueError(f"action must be 'wheels' or 'twist', got {action!r}")
        if goal not in ("world", "anywhere"):
            raise ValueError(f"goal must be 'world' or 'anywhere', got {goal!r}")
        for name, value in (("control_dt", control_dt), ("dt", dt), ("episode_seconds", episode_seconds)):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number of seconds, got {value!r}")
        self.task, self.action, self.goal, self.dt = task, action, goal, dt
        self.world = world_spec(world or TASKS[task])
        if task == "maze" and goal == "world" and not self.world.goals:
            raise ValueError(f"the maze task needs a world with a goal area (or goal='anywhere'); {self.world.name!r} has none")
        if task == "line" and not self.world.lines:
            raise ValueError(f"the line task needs a world with a line; {self.world.name!r} has none")
        if self.world.movables:
            raise ValueError(f"{self.world.name!r} has movable obstacles, which copies of an environment would share")
        self.robot = load_robot_spec(robot, noise=noise)
        if self.robot.chassis is not None:
            raise ValueError("the environments drive a differential-drive robot; a general chassis is not supported")
        self.substeps = max(1, round(control_dt / dt))
        self.control_dt = self.substeps * dt
        self.episode_steps = max(1, round(episode_seconds / self.control_dt))
        self.observation_space = observation_space(self.robot, task, self.world)
        spec = self.robot
        self.ranges = {kind.field: np.array([s.max_range for s in getattr(spec, kind.section)]) for kind in OBSERVED if kind.observed == "distance"}
        """What an observed distance reads where nothing is in range: each sensor's `max_range` (m)."""
        self.rim_per_tick = math.pi * spec.wheel_diameter / spec.encoders.ticks_per_rev / self.control_dt
        self.command_per_speed = np.array(command_per_speed(spec))  # (left, right)

    # --- what a seed draws ----------------------------------------------------------------------

    def draw_start(self, rng: np.random.Generator, world: World) -> tuple[float, float, float]:
        """A start pose: on the line (line task) or anywhere free (maze task)."""
        if self.task == "line":
            points = np.asarray(self.world.lines[0].points, dtype=np.float64)
            legs = np.diff(points, axis=0)
            lengths = np.hypot(legs[:, 0], legs[:, 1])
            at = rng.uniform(0.0, lengths.sum())
            k = min(int(np.searchsorted(np.cumsum(lengths), at)), len(legs) - 1)
            along = legs[k] / lengths[k]
            x, y = points[k] + along * (at - (np.cumsum(lengths)[k] - lengths[k]))
            offset, turn = rng.uniform(-LINE_OFFSET, LINE_OFFSET), rng.uniform(-LINE_TURN, LINE_TURN)
            return float(x - along[1] * offset), float(y + along[0] * offset), float(math.atan2(along[1], along[0]) + turn)
        x, y = self._free_point(rng, world, avoid_goals=True)
        return x, y, float(rng.uniform(-math.pi, math.pi))

    def draw_goal(self, rng: np.random.Generator, world: World) -> tuple[float, float]:
        """The maze task's goal: a point in one of the world's goal areas, or anywhere free."""
        if self.task != "maze":
            return math.nan, math.nan
        if self.goal == "anywhere":
            return self._free_point(rng, world, avoid_goals=False)
        area = self.world.goals[int(rng.integers(len(self.world.goals)))]
        xmin, ymin, xmax, ymax = area.box
        for _ in range(DRAWS):
            x, y = rng.uniform(xmin, xmax), rng.uniform(ymin, ymax)
            if area.contains(x, y):
                return float(x), float(y)
        raise ValueError(f"{self.world.name!r}: no point found inside a goal area")

    def _free_point(self, rng: np.random.Generator, world: World, avoid_goals: bool) -> tuple[float, float]:
        xmin, ymin, xmax, ymax = self.world.bounds
        reach = self.robot.body_radius + CLEARANCE
        query = world.robots[0].query_filter  # sees walls only: the copies' robots share its group
        for _ in range(DRAWS):
            x, y = rng.uniform(xmin + reach, xmax - reach), rng.uniform(ymin + reach, ymax - reach)
            if world.space.point_query((x, y), reach, query):
                continue
            if avoid_goals and any(g.box[0] - 0.2 < x < g.box[2] + 0.2 and g.box[1] - 0.2 < y < g.box[3] + 0.2 for g in self.world.goals):
                continue
            if not world.floor.hole_at(x, y):
                return float(x), float(y)
        raise ValueError(f"{self.world.name!r}: no free point found for a robot of radius {self.robot.body_radius} m")


class _Copies:
    """N copies of a task in one world whose robots do not meet, advanced one control step at a
    time together: the physics, observations and rewards of CtsimEnv (one copy) and
    CtsimVectorEnv (N) alike."""

    def __init__(self, task: _Task, n: int):
        self.task = task
        self.world = World(task.world, dt=task.dt, robots_meet=False)
        xmin, ymin, xmax, ymax = task.world.bounds
        for _ in range(n):  # placed for real by `restart`
            self.world.add_robot(task.robot, ((xmin + xmax) / 2, (ymin + ymax) / 2, 0.0), seed=0)
        self.n = n
        self.steps = np.zeros(n, dtype=np.int64)
        self.ticks = np.zeros((n, 2))
        self.goal = np.full((n, 2), math.nan)
        self.to_goal = np.zeros(n)
        self.collisions = np.zeros(n, dtype=np.int64)
        self.readings: SensorFrame | None = None

    def restart(self, i: int, rng: np.random.Generator, start: tuple[float, float, float] | None = None) -> None:
        """Copy i's new episode: start, goal and noise seed drawn from `rng` (in that order)."""
        drawn = self.task.draw_start(rng, self.world)
        self.goal[i] = self.task.draw_goal(rng, self.world)
        noise_seed = int(rng.integers(2**63 - 1))
        robot = self.world.reset_robot(i, drawn if start is None else start, seed=noise_seed)
        self.steps[i], self.ticks[i], self.collisions[i] = 0, 0.0, 0
        self.to_goal[i] = math.hypot(robot.pose[0] - self.goal[i, 0], robot.pose[1] - self.goal[i, 1])

    def advance(self, actions: np.ndarray, moving: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """One control step of every copy (the copies not `moving` stand still): poses before and after."""
        actions = np.asarray(actions, dtype=np.float64)
        if actions.size != 2 * self.n:
            raise ValueError(f"expected actions of shape ({self.n}, 2), got {actions.shape}" if self.n > 1 else f"expected an action of shape (2,), got {actions.shape}")
        actions = actions.reshape(self.n, 2)
        wrong = ~(np.isfinite(actions) & (np.abs(actions) <= 1.0))
        if wrong.any():
            copy, _ = np.argwhere(wrong)[0]
            where = f" (copy {copy})" if self.n > 1 else ""
            raise ValueError(f"an action must be two finite numbers in [-1, 1] (the action space), got {actions[copy].tolist()}{where}")
        commands = self._motor_commands(actions)
        commands[~moving] = 0.0
        world = self.world
        before = world.poses()
        self.ticks[:] = 0.0
        ticks = tally_rows(world.tallies)["ticks"]  # (the World's tallies, each step's counts written into them)
        for _ in range(self.task.substeps):
            world.step(commands)
            self.ticks += ticks
        self.steps += moving
        return before, world.poses()

    def _motor_commands(self, actions: np.ndarray) -> np.ndarray:
        """Motor commands (n, 2) for actions in [-1, 1], as `bots.commands.wheel_speeds_for`
        and `motor_commands` make them: rim speeds scaled into the top speed, curvature kept."""
        a = actions
        top = self.task.robot.max_wheel_surface_speed
        if self.task.action == "wheels":
            rims = a * top
        else:  # v = a0 top; omega = a1 2 top / track, so that each wheel differs by a1 top
            rims = np.stack((a[:, 0] - a[:, 1], a[:, 0] + a[:, 1]), axis=1) * top
        scale = np.maximum(np.abs(rims).max(axis=1), top) / top
        return rims / scale[:, None] * self.task.command_per_speed

    def observe(self) -> np.ndarray:
        """(n, obs) observations from a fresh reading of every copy's sensors."""
        frame = self.readings = self.world.read_all()
        task = self.task
        parts = []
        for kind in OBSERVED:
            values = frame.rows(kind.field)
            parts.append(np.where(np.isfinite(values), values, task.ranges[kind.field]) if kind.observed == "distance" else values / kind.full_scale)
        parts.append(self.ticks * task.rim_per_tick)
        if task.task == "maze":
            pose = self.world.poses()
            offset = self.goal - pose[:, :2]
            bearing = np.arctan2(offset[:, 1], offset[:, 0]) - pose[:, 2]
            parts.append(np.stack((np.hypot(offset[:, 0], offset[:, 1]), np.cos(bearing), np.sin(bearing)), axis=1))
        box = task.observation_space
        return np.clip(np.concatenate(parts, axis=1), box.low, box.high).astype(np.float32)

    def judge(self, before: np.ndarray, after: np.ndarray, moved: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Rewards and terminations (n,) of the control step from `before` to `after` (after
        `observe`) of the copies that `moved` (the others' are 0 and False)."""
        task, robots = self.task, self.world.robots
        collisions = np.array([r.collisions for r in robots], dtype=np.int64)
        new, self.collisions = collisions - self.collisions, collisions
        if task.task == "maze":
            distance = np.hypot(after[:, 0] - self.goal[:, 0], after[:, 1] - self.goal[:, 1])
            reward = (self.to_goal - distance) - TIME_COST * task.control_dt
            self.to_goal = np.where(moved, distance, self.to_goal)  # (a restarted copy's is its new start's)
            reached = distance < GOAL_REACH
            reward = reward + GOAL_BONUS * reached
        else:
            forward = (after[:, 0] - before[:, 0]) * np.cos(before[:, 2]) + (after[:, 1] - before[:, 1]) * np.sin(before[:, 2])
            on_line = (self.readings.rows("line") > LINE_SEEN).any(axis=1)  # (the line task's: its line sensors)
            reward = np.where(on_line, forward, -TIME_COST * task.control_dt)
            reached = np.zeros(self.n, dtype=bool)
        reward = reward - COLLISION_COST * new
        fallen = np.array([r.fallen for r in robots], dtype=bool)
        return np.where(moved, np.where(fallen, FALL_PENALTY, reward), 0.0), moved & (fallen | reached)

    def info(self) -> dict[str, np.ndarray]:
        """Per copy: episode time (s), pose (x, y m; heading rad), collisions, and (maze) the goal (x, y m)."""
        info = {"time": self.steps * self.task.control_dt, "pose": self.world.poses(), "collisions": self.collisions.copy()}
        return {**info, "goal": self.goal.copy()} if self.task.task == "maze" else info


class CtsimEnv(gymnasium.Env):
    """A c't-Bot in a world with a task (`"maze"` or `"line"`); see the module docstring.
    `noise`: a preset of `bots.noise` ("realistic", as every run by default; "none", "harsh")."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(
        self,
        task: str = "maze",
        world: str | WorldSpec | None = None,
        robot: str | RobotSpec = "ctbot",
        noise: str = DEFAULT_NOISE,
        action: str = "wheels",
        goal: str = "world",
        control_dt: float = 0.05,
        dt: float = DEFAULT_DT,
        episode_seconds: float = 60.0,
        render_mode: str | None = None,
        render_size: int = 400,
    ):
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self._task = _Task(task, world, robot, noise, action, goal, control_dt, dt, episode_seconds)
        self.task, self.action, self.dt, self.control_dt = task, action, dt, self._task.control_dt
        self.world_spec, self.robot_spec = self._task.world, self._task.robot
        self.episode_steps = self._task.episode_steps
        self.render_mode, self.render_size = render_mode, render_size
        self.observation_space = self._task.observation_space
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self._copies = _Copies(self._task, 1)
        self._started = False
        self._canvas: _Canvas | None = None

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        """A new episode: start pose, goal and sensor noise drawn from the env's generator.
        `options={"start": (x, y, heading)}` puts the robot there instead of the drawn start."""
        super().reset(seed=seed)
        self._copies.restart(0, self.np_random, (options or {}).get("start"))
        self._started = True
        return self._copies.observe()[0], _single(self._copies.info())

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        if not self._started:
            raise RuntimeError("call reset() before step()")
        copies = self._copies
        before, after = copies.advance(action, np.ones(1, dtype=bool))
        obs = copies.observe()
        reward, terminated = copies.judge(before, after, np.ones(1, dtype=bool))
        truncated = not terminated[0] and copies.steps[0] >= self.episode_steps
        return obs[0], float(reward[0]), bool(terminated[0]), bool(truncated), _single(copies.info())

    def render(self) -> np.ndarray | None:
        """An (H, W, 3) uint8 picture of the world, the robot and its goal (rgb_array mode)."""
        if self.render_mode != "rgb_array" or not self._started:
            return None
        if self._canvas is None:
            self._canvas = _Canvas(self.world_spec, self._copies.world, self.render_size)
        return self._canvas.frame(self._copies.world.robots[0].pose, self.robot_spec.body_radius, self._copies.goal[0])


def _single(info: dict[str, np.ndarray]) -> dict[str, Any]:
    single = {"time": float(info["time"][0]), "pose": info["pose"][0], "collisions": int(info["collisions"][0])}
    return {**single, "goal": info["goal"][0]} if "goal" in info else single


class CtsimVectorEnv(VectorEnv):
    """`num_envs` copies of CtsimEnv in one world, stepped as one batch: actions (N, 2) in,
    observations (N, obs) and rewards, terminated, truncated (N,) out; copy i is CtsimEnv reset
    with seed + i (or the i-th of a list of seeds). A copy whose episode ended is reset on the next
    step (Gymnasium's next-step autoreset), which returns its first observation and reward 0."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 4, render_mode: str | None = None, render_size: int = 400, **kwargs: Any):
        steps = kwargs.pop("max_episode_steps", None)  # make_vec passes the spec's (or the caller's): whichever limit comes first
        if steps is not None:
            kwargs["episode_seconds"] = min(kwargs.get("episode_seconds", 60.0), steps * kwargs.get("control_dt", 0.05))
        if not (isinstance(num_envs, int) and num_envs >= 1):
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        template = CtsimEnv(**kwargs)  # checks the arguments as the single env does
        self._task = template._task
        self.num_envs, self.render_mode, self.render_size = num_envs, render_mode, render_size
        self.single_observation_space = template.observation_space
        self.single_action_space = template.action_space
        self.observation_space = gymnasium.vector.utils.batch_space(self.single_observation_space, num_envs)
        self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, num_envs)
        self._copies = _Copies(self._task, num_envs)
        self._rngs: list[np.random.Generator | None] = [None] * num_envs
        self._ended = np.zeros(num_envs, dtype=bool)
        self._canvas: _Canvas | None = None

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        """Reset every copy (or those of `options["reset_mask"]`); an int seed gives copy i seed + i."""
        seeds = [seed + i for i in range(self.num_envs)] if isinstance(seed, int) else (seed if seed is not None else [None] * self.num_envs)
        if len(seeds) != self.num_envs:
            raise ValueError(f"a list of seeds needs one per copy ({self.num_envs}), got {len(seeds)}")
        options = dict(options or {})
        mask = np.asarray(options.pop("reset_mask", np.ones(self.num_envs, dtype=bool)), dtype=bool)
        if mask.shape != (self.num_envs,):
            raise ValueError(f"options['reset_mask'] must have shape ({self.num_envs},), got {mask.shape}")
        for i in np.flatnonzero(mask):
            if seeds[i] is not None or self._rngs[i] is None:
                self._rngs[i], _ = seeding.np_random(seeds[i])
            self._copies.restart(int(i), self._rngs[i], options.get("start"))
        self._ended[mask] = False
        return self._copies.observe(), self._infos()

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        if any(rng is None for rng in self._rngs):
            raise RuntimeError("call reset() before step()")
        copies, restarting = self._copies, self._ended.copy()
        before, after = copies.advance(actions, ~restarting)
        for i in np.flatnonzero(restarting):  # after the physics step, so that its noise draws are the new episode's
            copies.restart(int(i), self._rngs[i])
        obs = copies.observe()
        rewards, terminated = copies.judge(before, after, ~restarting)
        truncated = ~restarting & ~terminated & (copies.steps >= self._task.episode_steps)
        self._ended = terminated | truncated
        return obs, rewards, terminated, truncated, self._infos()

    def render(self) -> tuple[np.ndarray, ...] | None:
        """One picture per copy (rgb_array mode)."""
        if self.render_mode != "rgb_array" or self._rngs[0] is None:
            return None
        if self._canvas is None:
            self._canvas = _Canvas(self._task.world, self._copies.world, self.render_size)
        radius = self._task.robot.body_radius
        return tuple(self._canvas.frame(r.pose, radius, goal) for r, goal in zip(self._copies.world.robots, self._copies.goal))

    def _infos(self) -> dict[str, np.ndarray]:
        """Gymnasium's batched infos: each key's values of every copy, and `_key` saying each has one."""
        info = self._copies.info()
        return {**info, **{f"_{key}": np.ones(self.num_envs, dtype=bool) for key in info}}


class _Canvas:
    """Draws a world once (floor raster, walls, goals) and a robot on it per frame, with pygame."""

    def __init__(self, spec: WorldSpec, world: World, size: int):
        import pygame

        xmin, ymin, xmax, ymax = spec.bounds
        self.scale = size / max(xmax - xmin, ymax - ymin)
        self.origin = (xmin, ymax)
        width, height = max(1, round((xmax - xmin) * self.scale)), max(1, round((ymax - ymin) * self.scale))
        grey = 255 - (world.floor.value.astype(np.float64) * 255 / CNY70_MAX)  # floor raster, rows of y up
        grey[world.floor.hole] = 0
        picture = np.repeat(grey[::-1, :, None], 3, axis=2).astype(np.uint8)
        self.background = pygame.transform.smoothscale(pygame.surfarray.make_surface(picture.swapaxes(0, 1)), (width, height))
        for goal in spec.goals:
            pygame.draw.polygon(self.background, (120, 225, 140), [self._px(p) for p in goal.vertices])
        for wall in spec.walls:
            pygame.draw.polygon(self.background, (35, 40, 70), [self._px(p) for p in wall.vertices])

    def _px(self, point) -> tuple[int, int]:  # noqa: ANN001
        return round((point[0] - self.origin[0]) * self.scale), round((self.origin[1] - point[1]) * self.scale)

    def frame(self, pose: np.ndarray, radius: float, goal: np.ndarray) -> np.ndarray:
        import pygame

        surface = self.background.copy()
        if np.all(np.isfinite(goal)):
            pygame.draw.circle(surface, (225, 60, 60), self._px(goal), max(2, round(GOAL_REACH * self.scale)), width=2)
        centre = self._px(pose[:2])
        pygame.draw.circle(surface, (40, 150, 70), centre, max(2, round(radius * self.scale)))
        tip = pose[:2] + radius * np.array((math.cos(pose[2]), math.sin(pose[2])))
        pygame.draw.line(surface, (255, 255, 255), centre, self._px(tip), max(1, round(0.2 * radius * self.scale)))
        return np.ascontiguousarray(pygame.surfarray.array3d(surface).swapaxes(0, 1))


ENVIRONMENTS = {"ctsim/MazeNav-v0": {"task": "maze"}, "ctsim/LineFollow-v0": {"task": "line"}}
"""The registered environment ids and their arguments."""
EPISODE_STEPS = 1200
"""The registered episode limit (`spec.max_episode_steps`, Gymnasium's TimeLimit): the envs'
default 60 s of 0.05 s steps, so that wrappers and monitors see it."""

for _id, _kwargs in ENVIRONMENTS.items():
    if _id not in gymnasium.registry:
        gymnasium.register(_id, entry_point=f"{__name__}:CtsimEnv", vector_entry_point=f"{__name__}:CtsimVectorEnv", kwargs=_kwargs,
                           max_episode_steps=EPISODE_STEPS)  # fmt: skip
