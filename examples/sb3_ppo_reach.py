"""Stable-Baselines3 PPO on the clawfleet `reach` task, one policy shared by every arm (parameter sharing).

SuperSuit turns the PettingZoo env into a vector env whose rows are every arm of every cell
(`fleet.env.vector`), which SB3 trains like any vector env. Installs with the `rl` extra.

    python examples/sb3_ppo_reach.py --cells 2 --timesteps 200000 --save ppo_reach
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import supersuit
import torch
from stable_baselines3 import PPO
from stable_baselines3.common.logger import Logger

from fleet.env import parallel_env


def make_vec_env(cells: int, cpus: int, arms: int, max_cycles: int):
    """`cells` reach cells as one SB3 vector env (each arm a row), in `cpus` worker processes."""
    cell = supersuit.pettingzoo_env_to_vec_env_v1(parallel_env(scenario="reach", n_arms=arms, max_cycles=max_cycles))
    return supersuit.concat_vec_envs_v1(cell, cells, num_cpus=cpus, base_class="stable_baselines3")


def mean_return(model: PPO, arms: int, max_cycles: int, seed: int) -> float:
    """One evaluation episode with the shared policy acting for every arm: the mean return per arm."""
    env = parallel_env(scenario="reach", n_arms=arms, max_cycles=max_cycles)
    obs, _ = env.reset(seed=seed)
    total = {a: 0.0 for a in env.possible_agents}
    while env.agents:
        actions = {a: model.predict(obs[a], deterministic=True)[0] for a in env.agents}
        obs, rewards, *_ = env.step(actions)
        for a, r in rewards.items():
            total[a] += r
    env.close()
    return float(np.mean(list(total.values())))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cells", type=int, default=2)
    parser.add_argument("--cpus", type=int, default=0, help="worker processes (0: the cells run in this process)")
    parser.add_argument("--arms", type=int, default=2)
    parser.add_argument("--max-cycles", type=int, default=100)
    parser.add_argument("--timesteps", type=int, default=100_000, help="agent-steps to train for")
    parser.add_argument("--n-steps", type=int, default=256, help="PPO rollout length per row")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--save", help="save the trained policy here (.zip)")
    args = parser.parse_args()
    venv = make_vec_env(args.cells, args.cpus, args.arms, args.max_cycles)
    try:
        torch.manual_seed(args.seed)  # SuperSuit's SB3 vector env has no seed(): PPO(seed=...) would call it
        model = PPO(
            "MlpPolicy", venv, n_steps=args.n_steps, batch_size=min(256, args.n_steps * venv.num_envs), verbose=0
        )
        # SB3's default makes an empty SB3-<time> folder in /tmp
        model.set_logger(Logger(folder=None, output_formats=[]))
        before = mean_return(model, args.arms, args.max_cycles, seed=1000)
        start = time.perf_counter()
        model.learn(total_timesteps=args.timesteps)
        wall = time.perf_counter() - start
        after = mean_return(model, args.arms, args.max_cycles, seed=1000)
    finally:
        venv.close()
    print(
        f"trained {args.timesteps} agent-steps on {args.cells} cell(s) x {args.arms} arms in {wall:.0f} s "
        f"({args.timesteps / wall:,.0f} agent-steps/s); mean return per arm {before:.1f} -> {after:.1f}"
    )
    if args.save:
        model.save(args.save)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
