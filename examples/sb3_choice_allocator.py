"""A learned allocator, trained in the env and deployed in the real line: Stable-Baselines3 PPO in the allocate mode,
observing only each arm's choices (`observe="choices"`: what the coordinator can build) and stepping from choice to
choice (`choice_steps=True`), one policy shared by every arm. The trained policy is exported as a policy file, played
in the env against the coordinator's allocators on the same seeds, and is then an allocator of the real line:

    python examples/sb3_choice_allocator.py --scene mixed_infeed --load 1.0 --timesteps 20000 --save learned.pt2
    fleet sweep mixed_infeed --load 1.0 --allocator greedy optimal policy:learned.pt2 --seeds 0-19 --out sweep
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import supersuit
import torch
from allocate_mode_allocators import against, run_episode
from imitation import dagger, masked_player
from rich.progress import Progress
from stable_baselines3 import PPO
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.logger import Logger

from coordinator.allocation import make_allocator
from coordinator.policy_file import load_policy, save_policy
from fleet.common.scene_overrides import LOAD, scene_with
from fleet.env import parallel_env
from fleet.env.allocate_mode import allocator_actions


def cell(scene: str, max_cycles: int, decision_hz: float):
    """The allocate-mode cell a deployable policy trains in: choices only, a step per choice."""
    return parallel_env(
        scene=scene,
        scenario="line",
        action_mode="allocate",
        observe="choices",
        choice_steps=True,
        max_cycles=max_cycles,
        control_hz=decision_hz,
    )


class Logits(torch.nn.Module):
    """An SB3 actor-critic policy's actor, from choice features to action logits: what a policy file holds."""

    def __init__(self, policy) -> None:
        super().__init__()
        self.extract, self.body, self.head = (
            policy.pi_features_extractor,
            policy.mlp_extractor.policy_net,
            policy.action_net,
        )

    def forward(self, features: torch.Tensor) -> torch.Tensor:
        return self.head(self.body(self.extract(features)))


class Shown(BaseCallback):
    """Training's progress on the terminal: choices made of those asked for."""

    def __init__(self, progress: Progress, total: int) -> None:
        super().__init__()
        self.progress, self.bar = progress, progress.add_task("training (choices)", total=total)

    def _on_step(self) -> bool:
        self.progress.update(self.bar, completed=self.num_timesteps)
        return True


def file_policy(path: Path):
    """A policy file acting in the env as the coordinator's `policy:FILE` allocator acts (the best valid choice)."""
    return masked_player(load_policy(path).logits)


def play(scene: str, max_cycles: int, decision_hz: float, seed: int, player) -> dict:
    """One episode on `seed` played by `player`: an allocator's name, or a policy (`file_policy`); the line's counts."""
    env = cell(scene, max_cycles, decision_hz)
    if isinstance(player, str):
        allocator = make_allocator(player, env.scene)
        player = lambda env, _: allocator_actions(env.chooser, allocator, env._options)
    return run_episode(env, seed, player)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="mixed_infeed")
    parser.add_argument("--load", type=float, default=1.0, help="offered load the feeders are scaled to")
    parser.add_argument("--timesteps", type=int, default=20_000, help="agent-steps (choices) to train for")
    parser.add_argument("--max-cycles", type=int, default=600, help="an episode's decision periods")
    parser.add_argument("--decision-hz", type=float, default=10.0)
    parser.add_argument("--n-steps", type=int, default=128, help="PPO rollout length per arm")
    parser.add_argument("--episodes", type=int, default=5, help="evaluation episodes (seeds 1000...; 0: none)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--imitate",
        metavar="ALLOCATOR",
        help="start from this allocator's choices (DAgger, examples/imitation.py) before PPO; default: from scratch",
    )
    parser.add_argument("--dagger-rounds", type=int, default=4, help="with --imitate: rounds (0: the teacher plays)")
    parser.add_argument("--dagger-episodes", type=int, default=10, help="with --imitate: episodes a round")
    parser.add_argument("--save", type=Path, default=Path("learned_allocator.pt2"), help="the policy file to write")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="clawfleet-load-") as folder:  # the scaled scene's file, removed after
        return train_and_compare(args, scene_with(args.scene, {LOAD: args.load}, Path(folder)))


def train_and_compare(args: argparse.Namespace, scene: str) -> int:
    """Train on `scene` (a scene file at the asked load), save the policy, then play it against the built-ins."""
    venv = supersuit.pettingzoo_env_to_vec_env_v1(cell(scene, args.max_cycles, args.decision_hz))
    venv = supersuit.concat_vec_envs_v1(venv, 1, num_cpus=0, base_class="stable_baselines3")
    torch.manual_seed(args.seed)
    model = PPO("MlpPolicy", venv, n_steps=args.n_steps, batch_size=args.n_steps * venv.num_envs, verbose=0)
    model.set_logger(Logger(folder=None, output_formats=[]))
    start = time.perf_counter()
    trained_on = f"{args.scene} at load {args.load:g}, SB3 PPO, {args.timesteps} choices, seed {args.seed}"
    if args.imitate:  # seeds from 2000 on: apart from the evaluation's (1000...) and PPO's
        demos = dagger(
            Logits(model.policy),
            lambda: cell(scene, args.max_cycles, args.decision_hz),
            args.imitate,
            args.dagger_rounds,
            args.dagger_episodes,
            first_seed=2000,
        )
        trained_on += f", after DAgger from {args.imitate} ({len(demos.actions)} labelled choices)"
    if args.timesteps > 0:
        with Progress(transient=True) as progress:
            model.learn(total_timesteps=args.timesteps, callback=Shown(progress, args.timesteps))
    wall = time.perf_counter() - start
    venv.close()
    save_policy(Logits(model.policy), args.save, trained_on=trained_on)
    print(f"trained {args.timesteps} choices in {wall:.0f} s; policy file {args.save} ({trained_on})")
    if args.episodes < 1:
        return 0
    seeds = range(1000, 1000 + args.episodes)
    players = {"learned": file_policy(args.save), "greedy": "greedy", "optimal": "optimal"}
    runs = {name: [play(scene, args.max_cycles, args.decision_hz, s, p) for s in seeds] for name, p in players.items()}
    for name, rows in runs.items():
        completed = np.mean([r["completed"] for r in rows])
        print(f"{name}: {completed:.1f} parts an episode, vs greedy {against(rows, runs['greedy'])}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
