"""A learned allocator: RLlib PPO with action masking in the env's `allocate` mode, measured against the coordinator's.

Each arm chooses, when free, one of the (up to 4) tasks it may serve now, or to wait; the env's
action mask (`mask_in_observation=True`) goes into RLlib's action-masking module, so the policy
never picks an empty slot. One policy is shared by every arm. After training (`--minutes` or
`--iterations`) the policy plays the same seeded episodes as random, greedy, auction and optimal
(`examples/allocate_mode_allocators.py`), and the table and the learning curve (CSV, PNG) are written.

    python examples/rllib_masked_task_allocator.py --minutes 20 --curve docs/learned_allocator
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import gymnasium as gym
import numpy as np
import ray
import torch
from allocate_mode_allocators import POLICIES, against, line_totals, play
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.columns import Columns
from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
from ray.rllib.core.rl_module.rl_module import RLModuleSpec
from ray.rllib.env.multi_agent_env import MultiAgentEnv
from ray.rllib.examples.rl_modules.classes.action_masking_rlm import ActionMaskingTorchRLModule
from ray.tune.registry import register_env
from rich.console import Console
from rich.table import Table
from rllib_ppo_reach import start_ray
from train_ippo_reach import write_rows

from coordinator.choice_slots import WAIT
from fleet.env import parallel_env

ENV_NAME = "clawfleet_allocate_mode"


def cell(config: dict):
    """The allocate-mode cell, with the mask in each observation (PettingZoo's convention)."""
    return parallel_env(
        scene=config["scene"],
        scenario=config["scenario"],
        action_mode="allocate",
        n_arms=config["arms"],
        max_cycles=config["max_cycles"],
        control_hz=config["decision_hz"],
        mask_in_observation=True,
    )


def for_rllib(obs: dict) -> dict:
    """PettingZoo's `{observation, action_mask}` as RLlib's masking module names it (a float mask)."""
    return {"observations": obs["observation"], "action_mask": obs["action_mask"].astype(np.float32)}


class MaskedTaskEnv(MultiAgentEnv):
    """The allocate-mode cell as RLlib's multi-agent env, observations renamed for RLlib's action-masking module.

    Only decisions reach RLlib: on mixed_infeed an arm may only wait at 95% of the 10 Hz steps (busy, or nothing
    to take), and those steps are played here with every arm waiting, their rewards summed into the next step
    RLlib sees. An arm that waits while it could take a task is asked again `wait_s` later (or when another arm
    is asked), not at every tick: a wait is one decision, so a waiting policy does not fill its batches with
    ticks. The policy is evaluated through the same wrapper, so it decides at the same moments."""

    def __init__(self, config: dict) -> None:
        super().__init__()
        self.env = cell(config)
        self.agents = self.possible_agents = list(self.env.possible_agents)
        inner = self.env.observation_space(self.agents[0])
        one = gym.spaces.Dict(
            {
                "observations": inner["observation"],
                "action_mask": gym.spaces.Box(0.0, 1.0, inner["action_mask"].shape, np.float32),
            }
        )
        self.observation_spaces = {a: one for a in self.agents}
        self.action_spaces = {a: self.env.action_space(a) for a in self.agents}
        self.wait_ticks = max(1, round(config.get("wait_s", 0.5) * config["decision_hz"]))
        self._carried: dict[str, float] = {}
        self._waited_at: dict[str, int] = {}
        self._obs: dict = {}

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        obs, infos = self.env.reset(seed=seed, options=options)
        self._carried, self._waited_at = {a: 0.0 for a in self.agents}, {}
        obs, infos = self._to_next_choice(obs, infos, self._carried)
        return {a: for_rllib(o) for a, o in obs.items()}, infos

    def step(self, actions: dict):
        for a, k in actions.items():
            if k == WAIT and self._obs[a]["action_mask"][1:].any():
                self._waited_at[a] = self.env.cycles
        rewards, self._carried = self._carried, {a: 0.0 for a in self.agents}
        obs, step_rewards, terminated, truncated, infos = self.env.step(actions)
        for a, r in step_rewards.items():
            rewards[a] += r
        if self.env.agents:
            obs, infos = self._to_next_choice(obs, infos, rewards)
        terminated["__all__"], truncated["__all__"] = all(terminated.values()), all(truncated.values())
        return {a: for_rllib(o) for a, o in obs.items()}, rewards, terminated, truncated, infos

    def _asking(self, obs: dict) -> bool:
        """Whether an arm has a choice now and did not just wait on one."""
        return any(
            o["action_mask"][1:].any() and self.env.cycles - self._waited_at.get(a, -self.wait_ticks) >= self.wait_ticks
            for a, o in obs.items()
        )

    def _to_next_choice(self, obs: dict, infos: dict, rewards: dict) -> tuple[dict, dict]:
        """Every arm waits until one asks or one step is left (RLlib's last step ends the episode); the rewards
        meanwhile are added to `rewards`."""
        while self.env.cycles < self.env.max_cycles - 1 and not self._asking(obs):
            obs, step_rewards, _, _, infos = self.env.step({a: WAIT for a in self.env.agents})
            for a, r in step_rewards.items():
                rewards[a] += r
        self._obs = obs
        return obs, infos

    def close(self) -> None:
        self.env.close()


def env_config(args: argparse.Namespace) -> dict:
    return {
        "scene": args.scene,
        "scenario": args.scenario,
        "arms": args.arms,
        "max_cycles": args.max_cycles,
        "decision_hz": args.decision_hz,
        "wait_s": args.wait_s,
    }


def ppo_config(args: argparse.Namespace) -> PPOConfig:
    return (
        PPOConfig()
        .environment(ENV_NAME, env_config=env_config(args))
        .env_runners(
            num_env_runners=args.env_runners, rollout_fragment_length="auto", sample_timeout_s=600.0
        )  # RLlib drops a batch sampled past its 60 s default
        .multi_agent(policies={"shared"}, policy_mapping_fn=lambda agent_id, *a, **k: "shared")
        .rl_module(
            rl_module_spec=MultiRLModuleSpec(
                rl_module_specs={"shared": RLModuleSpec(module_class=ActionMaskingTorchRLModule)}
            )
        )
        .training(
            train_batch_size_per_learner=args.batch,
            minibatch_size=min(128, args.batch),
            num_epochs=args.epochs,
            lr=3e-4,
            gamma=0.99,
            entropy_coeff=0.01,
        )
        .debugging(seed=args.seed)
    )


class LearnedPolicy:
    """The trained module on the observations `MaskedTaskEnv` gives (RLlib's names): the most likely action
    (`sample=False`), or one drawn from its
    masked distribution as in training, from a seeded generator (`sample=True`)."""

    def __init__(self, module, sample: bool, seed: int = 0) -> None:
        self.module, self.sample = module, sample
        self.generator = torch.Generator().manual_seed(seed)

    def __call__(self, obs: dict) -> dict:
        agents = list(obs)
        batch = {
            Columns.OBS: {
                "observations": torch.as_tensor(np.stack([obs[a]["observations"] for a in agents])),
                "action_mask": torch.as_tensor(np.stack([obs[a]["action_mask"] for a in agents])),
            }
        }
        with torch.no_grad():
            logits = self.module.forward_inference(batch)[Columns.ACTION_DIST_INPUTS]
        if not self.sample:
            return dict(zip(agents, logits.argmax(-1).tolist()))
        return dict(
            zip(agents, torch.multinomial(torch.softmax(logits, -1), 1, generator=self.generator)[:, 0].tolist())
        )


def evaluate(module, sample: bool, args: argparse.Namespace, seed: int) -> dict:
    """One episode of the learned policy on the seed the allocators play, deciding when it did in training."""
    env = MaskedTaskEnv(env_config(args))
    policy = LearnedPolicy(module, sample, seed)
    obs, _ = env.reset(seed=seed)
    team_return, done = 0.0, False
    while not done:
        obs, rewards, terminated, truncated, _ = env.step(policy(obs))
        team_return += sum(rewards.values())
        done = terminated["__all__"] or truncated["__all__"]
    out = {"return": team_return, **line_totals(env.env)}
    env.close()
    return out


def train(args: argparse.Namespace) -> tuple[object, list[dict]]:
    register_env(ENV_NAME, lambda config: MaskedTaskEnv(config))
    algo = ppo_config(args).build_algo()
    curve, start = [], time.perf_counter()
    i = 0
    while (args.iterations and i < args.iterations) or (
        not args.iterations and time.perf_counter() - start < args.minutes * 60
    ):
        result = algo.train()
        i += 1
        ret = result.get("env_runners", {}).get("episode_return_mean")
        row = {
            "iteration": i,
            "wall_s": round(time.perf_counter() - start, 1),
            "env_steps": int(result.get("num_env_steps_sampled_lifetime", 0) or 0),
            "episode_return": float(ret) if ret is not None else math.nan,
        }
        curve.append(row)
        print(f"iteration {i}: episode return {row['episode_return']:.2f}, {row['wall_s']:.0f} s", flush=True)
    if args.save:
        algo.save_to_path(str(Path(args.save).resolve()))
    return algo.get_module("shared"), curve


def save_curve(curve: list[dict], baselines: dict[str, float], stem: Path) -> None:
    """The curve as CSV and a PNG with the allocators' returns as lines."""
    write_rows(curve, stem.with_suffix(".csv"))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 3.5))
    ax.plot(
        [r["wall_s"] / 60 for r in curve], [r["episode_return"] for r in curve], label="learned (training episodes)"
    )
    for name, value in baselines.items():
        ax.axhline(
            value,
            linestyle="--",
            linewidth=1,
            label=f"{name} (evaluation)",
            color=f"C{1 + list(baselines).index(name)}",
        )
    ax.set_xlabel("training wall time (min)")
    ax.set_ylabel("team return per episode")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(stem.with_suffix(".png"), dpi=110)
    plt.close(fig)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", choices=("line", "handover"), default="line")
    parser.add_argument(
        "--scene", default="mixed_infeed", help="the scene (default mixed_infeed: where the allocators differ most)"
    )
    parser.add_argument("--arms", type=int, default=2)
    parser.add_argument("--max-cycles", type=int, default=600, help="decisions per episode")
    parser.add_argument("--decision-hz", type=float, default=10.0)
    parser.add_argument(
        "--wait-s",
        type=float,
        default=0.5,
        help="an arm that waits while it could take a task is asked again this much later",
    )
    parser.add_argument("--minutes", type=float, default=20.0, help="training wall time (unless --iterations)")
    parser.add_argument("--iterations", type=int, default=0)
    parser.add_argument(
        "--batch",
        type=int,
        default=300,
        help="env steps per training batch (decisions: steps where no arm has a choice are not sampled)",
    )
    parser.add_argument("--epochs", type=int, default=8)
    parser.add_argument("--env-runners", type=int, default=2, help="RLlib env-runner actors (sampling processes)")
    parser.add_argument("--episodes", type=int, default=10, help="evaluation episodes (seeds 1000, 1001, ...)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--curve", help="write the learning curve here (STEM.csv, STEM.png)")
    parser.add_argument("--save", metavar="DIR", help="save the trained algorithm here (RLlib checkpoint)")
    parser.add_argument(
        "--address", help="an existing Ray cluster (HOST:PORT); default: a local instance on loopback only"
    )
    args = parser.parse_args()
    start_ray(args.address, args.env_runners)
    try:
        module, curve = train(args)
        seeds = [1000 + e for e in range(args.episodes)]
        results = {
            "learned (sampled)": [evaluate(module, True, args, s) for s in seeds],
            "learned (most likely)": [evaluate(module, False, args, s) for s in seeds],
        }
        for name in POLICIES:
            results[name] = [
                play(name, args.scenario, args.arms, args.max_cycles, s, args.decision_hz, args.scene) for s in seeds
            ]
    finally:
        ray.shutdown()
    table = Table(
        title=f"allocate mode on {args.scene}, {args.arms} arms: {len(seeds)} evaluation episodes of {args.max_cycles} "
        f"decisions at {args.decision_hz:g} Hz (seeds {seeds[0]}..{seeds[-1]})"
    )
    for column in (
        "policy",
        "team return",
        "parts completed / spawned",
        "parts per episode",
        "failed tasks",
        "against greedy (same seeds)",
    ):
        table.add_column(column)
    for name, runs in results.items():
        done = [r["completed"] for r in runs]
        table.add_row(
            name,
            f"{np.mean([r['return'] for r in runs]):.1f}",
            f"{sum(done)} / {sum(r['spawned'] for r in runs)}",
            f"{np.mean(done):.2f} ± {np.std(done, ddof=1) if len(done) > 1 else 0:.2f}",
            str(sum(r["failed"] for r in runs)),
            against(runs, results["greedy"]),
        )
    Console(width=140).print(table)
    if args.curve:
        save_curve(
            curve,
            {
                n: float(np.mean([r["return"] for r in runs]))
                for n, runs in results.items()
                if not n.startswith("learned")
            },
            Path(args.curve),
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
