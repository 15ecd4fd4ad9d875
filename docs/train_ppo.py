"""Train stable-baselines3's PPO on ctsim/LineFollow-v0 (or MazeNav-v0) and compare it with a
random policy: a real consumer of the Gymnasium environments (`sim/experiments/gym.py`).

    pip install torch==2.13.0 --index-url https://download.pytorch.org/whl/cpu   # a CPU build first
    pip install -e ".[rl]"
    python docs/train_ppo.py                      # LineFollow-v0, 300,000 env steps
    python docs/train_ppo.py --env ctsim/MazeNav-v0 --steps 1000000

It trains on CtsimVectorEnv (all copies in one world, one batch per step), then runs the trained
policy (deterministic) and a random policy for one episode on each of `--eval` copies with the same
seeds, and prints both mean returns and the wall time of training.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecEnv, VecMonitor

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import sim.experiments.gym  # noqa: E402,F401  (registers the environments)
from sim.experiments.gym import CtsimVectorEnv  # noqa: E402


class SB3Batch(VecEnv):
    """CtsimVectorEnv as stable-baselines3's VecEnv: SB3 resets a finished copy in the same step
    (its last observation in `infos[i]["terminal_observation"]`), Gymnasium's vector env on the
    next one; the ended copies are reset at once through `reset_mask`."""

    def __init__(self, env: CtsimVectorEnv):
        self.env = env
        super().__init__(env.num_envs, env.single_observation_space, env.single_action_space)

    def reset(self) -> np.ndarray:
        seeds = self._seeds if any(s is not None for s in self._seeds) else None
        obs, _ = self.env.reset(seed=seeds)
        self._reset_seeds()
        return obs

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[dict[str, Any]]]:
        obs, rewards, terminated, truncated, _ = self.env.step(self._actions)
        ended = terminated | truncated
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        if ended.any():
            for i in np.flatnonzero(ended):
                infos[i] = {"terminal_observation": obs[i].copy(), "TimeLimit.truncated": bool(truncated[i] and not terminated[i])}
            obs, _ = self.env.reset(options={"reset_mask": ended})
        return obs, rewards.astype(np.float32), ended, infos

    def close(self) -> None:
        self.env.close()

    def get_attr(self, attr_name: str, indices: Any = None) -> list[Any]:
        return [getattr(self.env, attr_name)] * len(self._get_indices(indices))

    def set_attr(self, attr_name: str, value: Any, indices: Any = None) -> None:
        setattr(self.env, attr_name, value)

    def env_method(self, method_name: str, *args: Any, indices: Any = None, **kwargs: Any) -> list[Any]:
        raise NotImplementedError("the copies share one world: no per-copy methods")

    def env_is_wrapped(self, wrapper_class: type, indices: Any = None) -> list[bool]:
        return [False] * len(self._get_indices(indices))


def episode_returns(env: CtsimVectorEnv, act, seed: int) -> np.ndarray:  # noqa: ANN001 (obs -> actions)
    """Each copy's return over its first episode (copies that ended stop counting)."""
    obs, _ = env.reset(seed=seed)
    total = np.zeros(env.num_envs)
    running = np.ones(env.num_envs, dtype=bool)
    while running.any():
        obs, rewards, terminated, truncated, _ = env.step(act(obs))
        total += np.where(running, rewards, 0.0)
        running &= ~(terminated | truncated)
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="ctsim/LineFollow-v0")
    parser.add_argument("--steps", type=int, default=300_000, help="env steps of training")
    parser.add_argument("--envs", type=int, default=16, help="copies in the training batch")
    parser.add_argument("--eval", type=int, default=16, help="evaluation episodes (one per copy)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--save", type=Path, help="write the trained policy here (.zip)")
    args = parser.parse_args()
    torch.set_num_threads(1)  # small networks: a second thread's hand-offs cost more than they save (17x on a busy 2-core machine)

    train = VecMonitor(SB3Batch(gym.make_vec(args.env, num_envs=args.envs).unwrapped))
    train.seed(args.seed)
    model = PPO("MlpPolicy", train, n_steps=256, batch_size=512, n_epochs=10, gamma=0.99, learning_rate=3e-4, seed=args.seed, device="cpu", verbose=0)
    start = time.perf_counter()
    model.learn(total_timesteps=args.steps)
    wall = time.perf_counter() - start
    if args.save:
        model.save(args.save)

    evaluation = gym.make_vec(args.env, num_envs=args.eval).unwrapped
    seed = 10_000 + args.seed  # episodes the training never saw
    trained = episode_returns(evaluation, lambda obs: model.predict(obs, deterministic=True)[0], seed)
    rng = np.random.default_rng(args.seed)
    random = episode_returns(evaluation, lambda obs: rng.uniform(-1, 1, (args.eval, 2)).astype(np.float32), seed)
    print(f"{args.env}: PPO, {args.steps:,} env steps in {wall:.0f} s ({args.steps / wall:,.0f} env-steps/s with learning)")
    print(f"return over {args.eval} episodes of {evaluation._task.episode_steps * evaluation._task.control_dt:g} s: "
          f"PPO {trained.mean():.2f} +- {trained.std():.2f}, random policy {random.mean():.2f} +- {random.std():.2f}")


if __name__ == "__main__":
    main()
