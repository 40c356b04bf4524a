"""RLlib multi-agent PPO on the clawfleet `reach` task, through RLlib's own PettingZoo wrapper.

One policy shared by every arm (`--policies shared`, the default) or one policy per arm
(`--policies per-arm`: the arm's id is the policy's id). Without `--address` it starts a local Ray
instance on loopback only (127.0.0.1, no dashboard); `--address HOST:PORT` trains on a Ray cluster
that is already running (`ray start --head ...`). Installs with the `rl` extra.

    python examples/rllib_ppo_reach.py --iterations 20 --policies per-arm --env-runners 1
"""

from __future__ import annotations

import argparse
import math
import time

import ray
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec
from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
from ray.tune.registry import register_env

from fleet.env import parallel_env

ENV_NAME = "clawfleet_reach"


def make_env(config: dict) -> ParallelPettingZooEnv:
    """A reach cell as RLlib's multi-agent env (the agents are the scene's arm ids)."""
    return ParallelPettingZooEnv(parallel_env(scenario="reach", n_arms=config["arms"], max_cycles=config["max_cycles"]))


def policy_ids(arms: int, policies: str) -> list[str]:
    """`shared`: one policy for all; `per-arm`: one per arm, named by the arm's id."""
    return ["shared"] if policies == "shared" else [f"arm_{i}" for i in range(arms)]


def ppo_config(args: argparse.Namespace) -> PPOConfig:
    ids = policy_ids(args.arms, args.policies)
    shared = args.policies == "shared"
    batch = args.batch
    return (
        PPOConfig()
        .environment(ENV_NAME, env_config={"arms": args.arms, "max_cycles": args.max_cycles})
        .env_runners(num_env_runners=args.env_runners, rollout_fragment_length="auto")
        .multi_agent(
            policies=set(ids),
            policy_mapping_fn=(lambda agent_id, *a, **k: "shared") if shared else (lambda agent_id, *a, **k: agent_id),
        )
        .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs={p: RLModuleSpec() for p in ids}))
        .training(train_batch_size_per_learner=batch, minibatch_size=min(128, batch), num_epochs=args.epochs, lr=3e-4)
        .debugging(seed=args.seed)
    )


def episode_return(result: dict) -> float:
    """The mean episode return (summed over arms) of the iteration's sampling, NaN before any episode ended."""
    runners = result.get("env_runners", {})
    value = runners.get("episode_return_mean", math.nan)
    return float(value) if value is not None else math.nan


def start_ray(address: str | None, env_runners: int) -> None:
    """Join the Ray cluster at `address`, or start a local instance on loopback only (no dashboard)."""
    if address:
        ray.init(address=address)
    else:
        ray.init(
            _node_ip_address="127.0.0.1", include_dashboard=False, num_cpus=max(2, env_runners + 1), log_to_driver=False
        )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=20)
    parser.add_argument("--arms", type=int, default=2)
    parser.add_argument("--max-cycles", type=int, default=100)
    parser.add_argument("--policies", choices=("shared", "per-arm"), default="shared")
    parser.add_argument("--env-runners", type=int, default=1, help="RLlib env-runner actors (0: sample in the driver)")
    parser.add_argument("--batch", type=int, default=1000, help="agent-steps per training batch")
    parser.add_argument("--epochs", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--address", help="an existing Ray cluster (HOST:PORT); default: a local instance on loopback only"
    )
    args = parser.parse_args()
    start_ray(args.address, args.env_runners)
    try:
        register_env(ENV_NAME, make_env)
        algo = ppo_config(args).build_algo()
        start, steps = time.perf_counter(), 0
        for i in range(args.iterations):
            result = algo.train()
            steps = int(result.get("num_env_steps_sampled_lifetime", steps) or steps)
            print(
                f"iteration {i + 1}: episode return {episode_return(result):.2f}, env steps {steps}, "
                f"{time.perf_counter() - start:.0f} s",
                flush=True,
            )
        print(
            f"trained {args.iterations} iteration(s) of PPO with policies "
            f"{', '.join(policy_ids(args.arms, args.policies))} "
            f"on {args.arms} arms"
        )
        algo.stop()
    finally:
        ray.shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
