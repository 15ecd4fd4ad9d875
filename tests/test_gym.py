"""Gymnasium environments: the checker passes, a random policy runs 10,000 steps inside the
spaces, seeded resets repeat, the vectorised env equals N separate envs, frames are pictures."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from sim.experiments.gym import ENVIRONMENTS, CtsimEnv, CtsimVectorEnv


@pytest.mark.parametrize("env_id", list(ENVIRONMENTS))
@pytest.mark.parametrize("action", ["wheels", "twist"])
def test_check_env_passes(env_id, action):
    env = gym.make(env_id, render_mode="rgb_array", action=action)
    check_env(env.unwrapped)


def test_random_policy_runs_10000_steps():
    """Both tasks, 5,000 steps each at a 20 ms control step; every observation inside its Box."""
    steps = 0
    for env_id in ENVIRONMENTS:
        env = gym.make(env_id, control_dt=0.02, episode_seconds=20.0)
        env.action_space.seed(1)
        obs, _ = env.reset(seed=1)
        episodes = 0
        for _ in range(5000):
            obs, reward, terminated, truncated, _ = env.step(env.action_space.sample())
            assert env.observation_space.contains(obs) and np.isfinite(reward)
            steps += 1
            if terminated or truncated:
                episodes += 1
                obs, _ = env.reset()
        assert episodes >= 4  # 5,000 steps of 20 ms are 100 s: the 20 s limit truncates
    assert steps == 10_000


def _rollout(env, seed: int, actions: np.ndarray) -> np.ndarray:
    obs = [env.reset(seed=seed)[0]]
    obs += [env.step(a)[0] for a in actions]
    return np.array(obs)


def test_seeded_reset_repeats():
    env = CtsimEnv("line")
    actions = np.random.default_rng(0).uniform(-1, 1, (50, 2)).astype(np.float32)
    assert np.array_equal(_rollout(env, 3, actions), _rollout(env, 3, actions))


def test_goal_terminates_with_the_bonus():
    env = CtsimEnv("maze")
    goal = np.mean(env.world_spec.goals[0].vertices, axis=0)
    env.reset(seed=0, options={"start": (goal[0], goal[1] - 0.01, np.pi / 2)})
    _, reward, terminated, truncated, _ = env.step(np.zeros(2, dtype=np.float32))
    assert terminated and not truncated and reward > 9  # +10 at the goal, less the time cost


def test_vector_env_equals_separate_envs():
    n, steps = 3, 40
    vec = gym.make_vec("ctsim/LineFollow-v0", num_envs=n)
    assert isinstance(vec.unwrapped, CtsimVectorEnv)
    actions = np.random.default_rng(2).uniform(-1, 1, (steps, n, 2)).astype(np.float32)
    obs, _ = vec.reset(seed=10)
    batched = [obs] + [vec.step(a)[0] for a in actions]
    separate = [_rollout(CtsimEnv("line"), 10 + i, actions[:, i]) for i in range(n)]
    assert np.array_equal(np.stack(batched, axis=1), np.stack(separate))


def test_render_draws_the_world():
    env = CtsimEnv("line", render_mode="rgb_array", render_size=200)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (140, 200, 3) and frame.dtype == np.uint8  # the line world is 4 x 2.8 m
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 3  # floor, line, walls, robot
