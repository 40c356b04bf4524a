"""Stable-Baselines3 PPO from pixels alone: one arm of `pick_cell` learns to bring its claw to the part on the belt
seeing only a 64x64 camera over the cell (CnnPolicy: no joint angles, no part pose), on the `pick_place` task's
reward. Then the trained policy and a random one play the same seeds, and the paired difference of their returns
is given with its 95% interval. Installs with the `rl` extra; renders on the CPU where no GPU is (docs/cameras.md).

    python examples/sb3_pixels_pick.py --timesteps 20000 --episodes 20
"""

from __future__ import annotations

import argparse
import time

import gymnasium
import numpy as np
import torch
from scipy import stats
from stable_baselines3 import PPO
from stable_baselines3.common.logger import Logger
from stable_baselines3.common.vec_env import DummyVecEnv

from fleet.env import parallel_env

TOP = {  # over arm_0 and its stretch of belt, straight down
    "name": "top",
    "pose": {"xyz": [0.05, 0.2, 0.55], "look_at": [0.05, 0.2, 0.0], "up": [0.0, 1.0, 0.0]},
    "width_px": 64,
    "height_px": 64,
    "fov_deg": 50,
    "images": ["rgb"],
}


class PixelPick(gymnasium.Env):
    """pick_cell's one arm as a single-agent Gymnasium env that observes only the `top` camera's RGB image."""

    def __init__(self, max_cycles: int) -> None:
        self.cell = parallel_env(scene="pick_cell", scenario="pick_place", max_cycles=max_cycles, cameras=[TOP])
        self.arm = self.cell.possible_agents[0]
        self.observation_space = self.cell.observation_space(self.arm)["top_rgb"]
        self.action_space = self.cell.action_space(self.arm)

    def reset(self, seed: int | None = None, options: dict | None = None):
        observations, _ = self.cell.reset(seed=seed)
        return observations[self.arm]["top_rgb"], {}

    def step(self, action):
        observations, rewards, terminations, truncations, infos = self.cell.step({self.arm: action})
        arm = self.arm
        return observations[arm]["top_rgb"], rewards[arm], terminations[arm], truncations[arm], infos[arm]

    def close(self) -> None:
        self.cell.close()


def episode_return(env: PixelPick, seed: int, act) -> float:
    """One episode's return with `act(observation)` choosing the actions."""
    observation, _ = env.reset(seed=seed)
    total, done = 0.0, False
    while not done:
        observation, reward, terminated, truncated, _ = env.step(act(observation))
        total += reward
        done = terminated or truncated
    return total


def paired_interval(trained: list[float], random: list[float]) -> tuple[float, float, float]:
    """The mean paired difference (trained - random, same seeds) and its 95% t interval."""
    diff = np.subtract(trained, random)
    half = stats.t.ppf(0.975, len(diff) - 1) * diff.std(ddof=1) / np.sqrt(len(diff)) if len(diff) > 1 else np.inf
    return float(diff.mean()), float(diff.mean() - half), float(diff.mean() + half)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=20_000)
    parser.add_argument("--n-steps", type=int, default=512, help="PPO rollout length per env")
    parser.add_argument("--max-cycles", type=int, default=60, help="env steps an episode")
    parser.add_argument("--episodes", type=int, default=20, help="evaluation episodes (seeds), each policy")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.manual_seed(args.seed)
    venv = DummyVecEnv([lambda: PixelPick(args.max_cycles)])
    model = PPO("CnnPolicy", venv, n_steps=args.n_steps, batch_size=64, seed=args.seed, verbose=0)
    model.set_logger(Logger(folder=None, output_formats=[]))  # SB3's default makes an empty folder in /tmp
    start = time.perf_counter()
    model.learn(total_timesteps=args.timesteps)
    wall = time.perf_counter() - start
    venv.close()
    env, rng = PixelPick(args.max_cycles), np.random.default_rng(args.seed)
    seeds = range(10_000, 10_000 + args.episodes)
    trained = [episode_return(env, s, lambda o: model.predict(o, deterministic=True)[0]) for s in seeds]
    random = [episode_return(env, s, lambda o: rng.uniform(-1, 1, env.action_space.shape)) for s in seeds]
    env.close()
    mean, low, high = paired_interval(trained, random)
    print(
        f"trained {args.timesteps} steps from 64x64 pixels in {wall:.0f} s ({args.timesteps / wall:.0f} steps/s); "
        f"over {args.episodes} seeds: trained {np.mean(trained):.2f}, random {np.mean(random):.2f}, "
        f"paired difference {mean:.2f} (95% interval {low:.2f} to {high:.2f})"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
