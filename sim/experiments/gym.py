"""Gymnasium environments: a c't-Bot learning a task from its own sensor readings.

    import gymnasium as gym
    import sim.experiments.gym  # registers ctsim/MazeNav-v0 and ctsim/LineFollow-v0
    env = gym.make("ctsim/MazeNav-v0", render_mode="rgb_array")
    envs = gym.make_vec("ctsim/MazeNav-v0", num_envs=8)   # CtsimVectorEnv: N worlds in one call

Observation (float32): IR distances (m, nothing in range reads the far limit), line, border and
light sensors (0 white/bright .. 1 black/dark), and the wheel rim speeds the encoders measured over
the last control step (m/s). Action in [-1, 1]^2: wheel speeds as fractions of the top rim speed
(`action="wheels"`), or a twist (v, omega) as fractions of the top speed and of the top turn rate
(`action="twist"`). One env step is `control_dt` seconds (several physics steps of `dt`).

Tasks: `maze` (reach the world's goal area; reward: metres of progress towards it, a small cost
per second and per collision, +10 at the goal) and `line` (follow the floor line; reward: metres
driven forward while a line sensor sees the line, a small cost per second off it). Both end
(`terminated`) when the robot falls into a hole (-10) and are `truncated` after
`episode_seconds` of simulated time.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv

from bots.commands import Twist, WheelSpeeds, motor_commands, wheel_speeds_for
from bots.spec import RobotSpec
from sim.experiments.api import robot as load_robot_spec
from sim.experiments.api import world as world_spec
from sim.world import World, WorldSpec
from sim.world.readings import Readings
from sim.world.sensors import CNY70_MAX, LDR_MAX

TASKS = {"maze": "maze", "line": "line"}
"""Task name -> the shipped world it runs in by default."""
GOAL_BONUS = 10.0
FALL_PENALTY = -10.0
TIME_COST = 0.2
"""Reward lost per simulated second (per second off the line in the line task)."""
COLLISION_COST = 0.1
LINE_SEEN = 512
"""A CNY70 value above this (0 white .. 1023 black) sees the line."""


def observation_space(spec: RobotSpec) -> spaces.Box:
    """The Box of a robot's observations (see the module docstring for the order)."""
    top = 2.0 * spec.max_wheel_surface_speed  # encoders under slip can read above the motors' limit
    low = [0.0] * len(spec.ir) + [0.0] * (len(spec.line) + len(spec.border) + len(spec.light)) + [-top, -top]
    high = [s.max_range for s in spec.ir] + [1.0] * (len(spec.line) + len(spec.border) + len(spec.light)) + [top, top]
    return spaces.Box(np.array(low, np.float32), np.array(high, np.float32), dtype=np.float32)


@dataclass
class _Episode:
    """One world with one robot, advanced one control step at a time; the state a reward needs."""

    world: World
    spec: RobotSpec
    task: str
    readings: Readings
    ticks: np.ndarray
    distance_to_goal: float
    collisions: int = 0

    def observe(self, box: spaces.Box, control_dt: float) -> np.ndarray:
        r, spec = self.readings, self.spec
        ir = np.where(np.isfinite(r.ir_distance), r.ir_distance, [s.max_range for s in spec.ir])
        rim = self.ticks / spec.encoders.ticks_per_rev * math.pi * spec.wheel_diameter / control_dt
        values = np.concatenate([ir, r.line / CNY70_MAX, r.border / CNY70_MAX, r.light / LDR_MAX, rim])
        return np.clip(values, box.low, box.high).astype(np.float32)


def _goal_centre(world: WorldSpec) -> np.ndarray:
    return np.mean(np.asarray(world.goals[0].vertices), axis=0)


class CtsimEnv(gymnasium.Env):
    """A robot in a world with a task (`"maze"` or `"line"`); see the module docstring."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(
        self,
        task: str = "maze",
        world: str | WorldSpec | None = None,
        robot: str | RobotSpec = "ctbot",
        action: str = "wheels",
        control_dt: float = 0.05,
        dt: float = 0.01,
        episode_seconds: float = 60.0,
        render_mode: str | None = None,
        render_size: int = 400,
    ):
        if task not in TASKS:
            raise ValueError(f"unknown task {task!r} (tasks: {', '.join(TASKS)})")
        if action not in ("wheels", "twist"):
            raise ValueError(f"action must be 'wheels' or 'twist', got {action!r}")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.task, self.action, self.dt = task, action, dt
        self.world_spec = world_spec(world or TASKS[task])
        if task == "maze" and not self.world_spec.goals:
            raise ValueError(f"the maze task needs a world with a goal area; {self.world_spec.name!r} has none")
        self.robot_spec = load_robot_spec(robot)
        self.substeps = max(1, round(control_dt / dt))
        self.control_dt = self.substeps * dt
        self.episode_steps = max(1, round(episode_seconds / self.control_dt))
        self.render_mode, self.render_size = render_mode, render_size
        self.observation_space = observation_space(self.robot_spec)
        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self._episode: _Episode | None = None
        self._steps = 0
        self._canvas: Any = None

    # --- the Gymnasium interface ----------------------------------------------------------------

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        """A new episode; the world's sensor noise is seeded from the env's generator.
        `options={"start": (x, y, heading)}` overrides the world's start pose."""
        super().reset(seed=seed)
        world = World(self.world_spec, dt=self.dt, seed=int(self.np_random.integers(2**63 - 1)))
        robot = world.add_robot(self.robot_spec, (options or {}).get("start"))
        goal = float(np.hypot(*(robot.pose[:2] - _goal_centre(self.world_spec)))) if self.task == "maze" else math.nan
        self._episode = _Episode(world, self.robot_spec, self.task, world.read_all()[0], np.zeros(2), goal)
        self._steps = 0
        return self._episode.observe(self.observation_space, self.control_dt), self._info()

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        episode = self._episode
        if episode is None:
            raise RuntimeError("call reset() before step()")
        left, right = self._wheel_speeds(np.asarray(action, dtype=np.float64))
        commands = np.array([motor_commands(left, right, self.robot_spec)])
        world, robot = episode.world, episode.world.robots[0]
        before = robot.pose
        episode.ticks = np.zeros(2)
        for _ in range(self.substeps):
            world.step(commands)
            episode.readings = world.read_all()[0]
            episode.ticks = episode.ticks + episode.readings.encoder_ticks
        self._steps += 1
        reward, terminated = self._reward(episode, before, robot.pose, robot)
        truncated = not terminated and self._steps >= self.episode_steps
        return episode.observe(self.observation_space, self.control_dt), reward, terminated, truncated, self._info()

    def render(self) -> np.ndarray | None:
        """An (H, W, 3) uint8 picture of the world and the robot (rgb_array mode)."""
        if self.render_mode != "rgb_array" or self._episode is None:
            return None
        if self._canvas is None:
            self._canvas = _Canvas(self.world_spec, self._episode.world, self.render_size)
        return self._canvas.frame(self._episode.world.robots[0].pose, self.robot_spec.body_radius)

    # --- the task -------------------------------------------------------------------------------

    def _wheel_speeds(self, action: np.ndarray) -> tuple[float, float]:
        a = np.clip(np.nan_to_num(action, nan=0.0), -1.0, 1.0)
        top = self.robot_spec.max_wheel_surface_speed
        if self.action == "wheels":
            return wheel_speeds_for(WheelSpeeds(a[0] * top, a[1] * top), self.robot_spec)
        return wheel_speeds_for(Twist(a[0] * top, a[1] * 2 * top / self.robot_spec.track_width), self.robot_spec)

    def _reward(self, episode: _Episode, before: np.ndarray, after: np.ndarray, robot) -> tuple[float, bool]:  # noqa: ANN001
        if robot.fallen:
            return FALL_PENALTY, True
        new_collisions = robot.collisions - episode.collisions
        episode.collisions = robot.collisions
        if self.task == "maze":
            distance = float(np.hypot(*(after[:2] - _goal_centre(self.world_spec))))
            progress, episode.distance_to_goal = episode.distance_to_goal - distance, distance
            reward = progress - TIME_COST * self.control_dt - COLLISION_COST * new_collisions
            if self.world_spec.in_goal(float(after[0]), float(after[1])):
                return reward + GOAL_BONUS, True
            return reward, False
        forward = float(np.dot(after[:2] - before[:2], (math.cos(before[2]), math.sin(before[2]))))
        on_line = bool(np.any(episode.readings.line > LINE_SEEN))
        reward = forward if on_line else -TIME_COST * self.control_dt
        return reward - COLLISION_COST * new_collisions, False

    def _info(self) -> dict[str, Any]:
        robot = self._episode.world.robots[0]
        return {"time": self._episode.world.time, "pose": robot.pose, "collisions": robot.collisions}


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

    def frame(self, pose: np.ndarray, radius: float) -> np.ndarray:
        import pygame

        surface = self.background.copy()
        centre = self._px(pose[:2])
        pygame.draw.circle(surface, (40, 150, 70), centre, max(2, round(radius * self.scale)))
        tip = pose[:2] + radius * np.array((math.cos(pose[2]), math.sin(pose[2])))
        pygame.draw.line(surface, (255, 255, 255), centre, self._px(tip), max(1, round(0.2 * radius * self.scale)))
        return np.ascontiguousarray(pygame.surfarray.array3d(surface).swapaxes(0, 1))


class CtsimVectorEnv(VectorEnv):
    """`num_envs` copies of CtsimEnv stepped together in one call: actions (N, 2) in, observations
    (N, obs) and rewards, terminated, truncated (N,) out. A copy whose episode ended is reset on
    the next step (Gymnasium's next-step autoreset), which returns its first observation, reward 0."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20, "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 4, **kwargs: Any):
        kwargs.pop("max_episode_steps", None)  # make_vec passes the spec's; ours is episode_seconds
        self.envs = [CtsimEnv(**kwargs) for _ in range(num_envs)]
        self.num_envs = num_envs
        self.render_mode = self.envs[0].render_mode
        self.single_observation_space = self.envs[0].observation_space
        self.single_action_space = self.envs[0].action_space
        self.observation_space = gymnasium.vector.utils.batch_space(self.single_observation_space, num_envs)
        self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, num_envs)
        self._ended = np.zeros(num_envs, dtype=bool)

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict]:
        """Reset every copy; an int seed gives copy i the seed + i."""
        seeds = [seed + i for i in range(self.num_envs)] if isinstance(seed, int) else (seed or [None] * self.num_envs)
        results = [env.reset(seed=s, options=options) for env, s in zip(self.envs, seeds)]
        self._ended[:] = False
        return np.stack([obs for obs, _ in results]), self._infos([info for _, info in results])

    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict]:
        actions = np.asarray(actions)
        obs = np.empty((self.num_envs, *self.single_observation_space.shape), dtype=np.float32)
        rewards = np.zeros(self.num_envs)
        terminated = np.zeros(self.num_envs, dtype=bool)
        truncated = np.zeros(self.num_envs, dtype=bool)
        infos = []
        for i, env in enumerate(self.envs):
            if self._ended[i]:
                obs[i], info = env.reset()
            else:
                obs[i], rewards[i], terminated[i], truncated[i], info = env.step(actions[i])
            infos.append(info)
        self._ended = terminated | truncated
        return obs, rewards, terminated, truncated, self._infos(infos)

    def render(self) -> tuple[np.ndarray, ...] | None:
        frames = [env.render() for env in self.envs]
        return None if frames[0] is None else tuple(frames)

    def _infos(self, infos: list[dict]) -> dict:
        batched: dict = {}
        for i, info in enumerate(infos):
            batched = self._add_info(batched, info, i)
        return batched


ENVIRONMENTS = {"ctsim/MazeNav-v0": {"task": "maze"}, "ctsim/LineFollow-v0": {"task": "line"}}
"""The registered environment ids and their arguments."""

for _id, _kwargs in ENVIRONMENTS.items():
    if _id not in gymnasium.registry:
        gymnasium.register(_id, entry_point=f"{__name__}:CtsimEnv", vector_entry_point=f"{__name__}:CtsimVectorEnv", kwargs=_kwargs)
