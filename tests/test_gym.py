"""Gymnasium environments: the checker passes, a random policy runs 10,000 steps inside the
spaces, a seed draws the start, the goal and the noise and nothing else, the batched vector env
equals N separate envs step for step (autoresets included), and so does the one-process-per-env
vector env; frames are pictures."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from sim.experiments.gym import ENVIRONMENTS, GOAL_BONUS, CtsimEnv, CtsimVectorEnv


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


def _rollout(env, seed: int | None, actions: np.ndarray, options: dict | None = None) -> np.ndarray:
    obs = [env.reset(seed=seed, options=options)[0]]
    obs += [env.step(a)[0] for a in actions]
    return np.array(obs)


IDS = {"line": "ctsim/LineFollow-v0", "maze": "ctsim/MazeNav-v0"}
ACTIONS = np.random.default_rng(0).uniform(-1, 1, (30, 2)).astype(np.float32)


@pytest.mark.parametrize("task", ["line", "maze"])
def test_a_seed_repeats_its_episode_bit_for_bit(task):
    env = CtsimEnv(task)
    assert np.array_equal(_rollout(env, 3, ACTIONS), _rollout(CtsimEnv(task), 3, ACTIONS))


def test_seeds_draw_start_and_goal_and_the_noise_cannot_move_them():
    """Different seeds: different start poses and goals. The same seed: the same start and goal
    whatever the noise (the start and the goal are drawn before the noise seed)."""
    starts, goals = [], []
    for seed in range(5):
        _, quiet = CtsimEnv("maze", noise="none").reset(seed=seed)
        _, noisy = CtsimEnv("maze", noise="harsh").reset(seed=seed)
        assert np.array_equal(quiet["pose"], noisy["pose"]) and np.array_equal(quiet["goal"], noisy["goal"])
        starts.append(tuple(quiet["pose"]))
        goals.append(tuple(quiet["goal"]))
    assert len(set(starts)) == 5 and len(set(goals)) == 5


@pytest.mark.parametrize("task", ["line", "maze"])
def test_a_seed_changes_only_start_goal_and_noise(task):
    """Without noise and with the start given, two seeds give the same episode (the line task has
    no goal; the maze task's goal is drawn, so it is given too); with noise they do not."""
    start = {"line": (1.5, 0.6, 0.0), "maze": (0.36, 0.36, np.pi / 2)}[task]
    quiet = CtsimEnv(task, noise="none", goal="world")
    a, b = _rollout(quiet, 1, ACTIONS, {"start": start}), _rollout(quiet, 2, ACTIONS, {"start": start})
    if task == "maze":  # the goal differs: only the observation's last three (goal distance, bearing) may
        a, b = a[:, :-3], b[:, :-3]
    assert np.array_equal(a, b)
    noisy = CtsimEnv(task)
    assert not np.array_equal(_rollout(noisy, 1, ACTIONS, {"start": start}), _rollout(noisy, 2, ACTIONS, {"start": start}))


def test_goal_terminates_with_the_bonus():
    env = CtsimEnv("maze")
    _, info = env.reset(seed=0)
    goal = info["goal"]
    env.reset(seed=0, options={"start": (goal[0], goal[1] - 0.05, np.pi / 2)})
    _, reward, terminated, truncated, _ = env.step(np.zeros(2, dtype=np.float32))
    assert terminated and not truncated and reward > GOAL_BONUS - 1  # less the time cost of one step


def _separate(n: int, seed: int, actions: np.ndarray, **kwargs) -> tuple[np.ndarray, ...]:
    """N CtsimEnvs driven as Gymnasium's next-step autoreset drives the copies of a vector env."""
    envs = [CtsimEnv(**kwargs) for _ in range(n)]
    obs = [[env.reset(seed=seed + i)[0] for i, env in enumerate(envs)]]
    rewards, ends = [], []
    ended = [False] * n
    for step in actions:
        row, reward, end = [], [], []
        for i, env in enumerate(envs):
            if ended[i]:
                o, r, te, tr = env.reset()[0], 0.0, False, False
            else:
                o, r, te, tr, _ = env.step(step[i])
            ended[i] = te or tr
            row.append(o), reward.append(r), end.append((te, tr))
        obs.append(row), rewards.append(reward), ends.append(end)
    return np.array(obs), np.array(rewards), np.array(ends)


def _batched(vec, seed: int, actions: np.ndarray) -> tuple[np.ndarray, ...]:
    obs = [vec.reset(seed=seed)[0]]
    rewards, ends = [], []
    for step in actions:
        o, r, te, tr, _ = vec.step(step)
        obs.append(o), rewards.append(r), ends.append(np.stack((te, tr), axis=1))
    return np.array(obs), np.array(rewards), np.array(ends)


@pytest.mark.parametrize("task", ["line", "maze"])
def test_batched_vector_env_equals_separate_envs_step_for_step(task):
    """Copies in one world of robots that do not meet: the same observations, rewards and ends
    as separate envs, bit for bit, across episodes (0.5 s episodes: ten steps, then an autoreset)."""
    n, steps = 4, 45
    kwargs = {"task": task, "episode_seconds": 0.5}
    vec = gym.make_vec(IDS[task], num_envs=n, episode_seconds=0.5)
    assert isinstance(vec.unwrapped, CtsimVectorEnv)
    actions = np.random.default_rng(2).uniform(-1, 1, (steps, n, 2)).astype(np.float32)
    batched, separate = _batched(vec, 10, actions), _separate(n, 10, actions, **kwargs)
    assert separate[2].any()  # episodes did end inside the comparison
    for got, expected in zip(batched, separate):
        assert np.array_equal(got, expected)


def test_process_per_env_vector_env_equals_the_batched_one():
    n, steps = 2, 12
    actions = np.random.default_rng(3).uniform(-1, 1, (steps, n, 2)).astype(np.float32)
    processes = gym.make_vec("ctsim/LineFollow-v0", num_envs=n, vectorization_mode="async", episode_seconds=0.3)
    try:
        assert isinstance(processes, gym.vector.AsyncVectorEnv)
        got = _batched(processes, 5, actions)
    finally:
        processes.close()
    expected = _batched(CtsimVectorEnv(n, task="line", episode_seconds=0.3), 5, actions)
    for a, b in zip(got, expected):
        assert np.array_equal(a, b)


def test_vector_env_refuses_bad_seeds_and_masks():
    vec = CtsimVectorEnv(3, task="line")
    with pytest.raises(ValueError, match="one per copy"):
        vec.reset(seed=[1, 2])
    with pytest.raises(RuntimeError, match="reset"):
        vec.step(np.zeros((3, 2), dtype=np.float32))
    vec.reset(seed=0)
    obs, _ = vec.reset(options={"reset_mask": np.array([False, True, False])})
    assert obs.shape == (3, vec.single_observation_space.shape[0])


def test_render_draws_the_world():
    env = CtsimEnv("line", render_mode="rgb_array", render_size=200)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (140, 200, 3) and frame.dtype == np.uint8  # the line world is 4 x 2.8 m
    assert len(np.unique(frame.reshape(-1, 3), axis=0)) > 3  # floor, line, walls, robot


def test_the_ppo_example_trains_and_evaluates(monkeypatch, capsys):
    """docs/train_ppo.py end to end on a tiny budget (one rollout), where the extra `rl` is installed."""
    pytest.importorskip("stable_baselines3", reason="the optional extra rl (stable-baselines3) is not installed")
    import runpy
    from pathlib import Path

    example = Path(__file__).resolve().parents[1] / "docs" / "train_ppo.py"
    monkeypatch.setattr("sys.argv", [str(example), "--steps", "1", "--envs", "2", "--eval", "2"])
    runpy.run_path(str(example), run_name="__main__")
    out = capsys.readouterr().out
    assert "ctsim/LineFollow-v0: PPO, 1 env steps" in out and "random policy" in out


@pytest.mark.parametrize("action", ["wheels", "twist"])
def test_batched_motor_commands_equal_the_run_loops_conversion(action):
    """The vector env's numpy conversion of actions is the twin of `bots.commands` per robot."""
    from bots.commands import Twist, WheelSpeeds, motor_commands, wheel_speeds_for

    vec = CtsimVectorEnv(50, task="line", action=action)
    spec = vec._task.robot
    top = spec.max_wheel_surface_speed
    actions = np.random.default_rng(4).uniform(-1.0, 1.0, (50, 2))  # (beyond the Box: refused, see below)
    got = vec._copies._motor_commands(actions)
    for (a0, a1), row in zip(actions, got):
        command = WheelSpeeds(a0 * top, a1 * top) if action == "wheels" else Twist(a0 * top, a1 * 2 * top / spec.track_width)
        # the twist's wheel speeds round omega * track / 2 once more than the batched a1 * top: 1e-12 of 255
        np.testing.assert_allclose(row, motor_commands(*wheel_speeds_for(command, spec), spec), rtol=0, atol=1e-9)


def test_the_episode_limit_is_in_the_registered_spec_with_timelimit_semantics():
    """Wrappers and monitors see the limit (`spec.max_episode_steps`); gym.make's TimeLimit
    truncates at it, a shorter one asked of make included."""
    import gymnasium as gym

    assert gym.spec("ctsim/MazeNav-v0").max_episode_steps == 1200 and gym.spec("ctsim/LineFollow-v0").max_episode_steps == 1200
    env = gym.make("ctsim/LineFollow-v0", max_episode_steps=5)
    env.reset(seed=0)
    ends = [env.step(np.zeros(2, np.float32))[3] for _ in range(5)]
    assert ends == [False] * 4 + [True]
    envs = gym.make_vec("ctsim/LineFollow-v0", num_envs=2, max_episode_steps=3)
    envs.reset(seed=0)
    assert [bool(envs.step(np.zeros((2, 2), np.float32))[3].all()) for _ in range(3)] == [False, False, True]


@pytest.mark.parametrize("action", [[np.nan, 0.0], [0.0, np.inf], [1.5, 0.0], [0.0, -1.01]])
def test_an_action_outside_the_action_space_is_refused_with_a_clear_error(action):
    from sim.experiments.gym import CtsimEnv, CtsimVectorEnv

    env = CtsimEnv("line")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"two finite numbers in \[-1, 1\]"):
        env.step(np.array(action, np.float32))
    envs = CtsimVectorEnv(2, task="line")
    envs.reset(seed=0)
    with pytest.raises(ValueError, match=r"\(copy 1\)"):
        envs.step(np.array([[0.0, 0.0], action], np.float32))


def test_gymnasiums_checkers_find_nothing():
    """check_env, and the passive checker gym.make wraps every env in, without a warning."""
    import warnings

    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for name in ("ctsim/MazeNav-v0", "ctsim/LineFollow-v0"):
            env = gym.make(name)
            check_env(env.unwrapped)
            env.reset(seed=1)
            for _ in range(3):
                env.step(env.action_space.sample())
