"""A random-policy rollout of the clawfleet PettingZoo env: the baseline every learning curve starts from.

python examples/random_rollout.py --arms 2 --episodes 3 --max-cycles 200
"""

from __future__ import annotations

import argparse

import numpy as np

from fleet.env import parallel_env


def rollout(arms: int, episodes: int, max_cycles: int, seed: int) -> list[float]:
    """Mean return per agent of each episode under uniformly random actions."""
    env = parallel_env(n_arms=arms, scenario="reach", max_cycles=max_cycles)
    returns = []
    for episode in range(episodes):
        env.reset(seed=seed + episode)
        for agent in env.possible_agents:
            env.action_space(agent).seed(seed + episode)
        total = dict.fromkeys(env.possible_agents, 0.0)
        while env.agents:
            actions = {a: env.action_space(a).sample() for a in env.agents}
            _, rewards, _, _, _ = env.step(actions)
            for a, r in rewards.items():
                total[a] += r
        returns.append(float(np.mean(list(total.values()))))
    env.close()
    return returns


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--arms", type=int, default=2)
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--max-cycles", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    for i, r in enumerate(rollout(args.arms, args.episodes, args.max_cycles, args.seed)):
        print(f"episode {i}: mean return per arm {r:.2f}")


if __name__ == "__main__":
    main()
