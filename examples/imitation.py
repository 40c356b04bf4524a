"""Imitation before reinforcement: DAgger (Ross, Gordon and Bagnell, 2011) from one of the coordinator's allocators
into an SB3 policy's actor, in the allocate mode's choice steps. PPO from scratch needs far more choices than a
laptop gives it to find what an allocator already knows (wait for the part only you can take); a policy that starts
from the teacher's choices and is then trained on the line's own reward starts where the teacher is.

Round 0 lets the teacher play and records, for every arm that has a choice, what the teacher chose; each later round
lets the policy play and the teacher label the states the policy itself reaches (so it learns to recover from its
own mistakes, which plain behaviour cloning never sees). After each round the actor is fitted to every label so far
by the masked cross-entropy: invalid actions are out, as `masked_choice` leaves them out when the policy is used.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch
from allocate_mode_allocators import run_episode

from coordinator.allocation import make_allocator
from coordinator.choice_slots import masked_choice
from fleet.env.allocate_mode import allocator_actions


@dataclass
class Demonstrations:
    """Labelled choices: an arm's choice features, its action mask and the teacher's action there."""

    features: list[np.ndarray] = field(default_factory=list)
    masks: list[np.ndarray] = field(default_factory=list)
    actions: list[int] = field(default_factory=list)

    def add(self, features: np.ndarray, mask: np.ndarray, action: int) -> None:
        self.features.append(np.asarray(features, np.float32))
        self.masks.append(np.asarray(mask, bool))
        self.actions.append(int(action))

    def tensors(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        return (
            torch.from_numpy(np.stack(self.features)),
            torch.from_numpy(np.stack(self.masks)),
            torch.tensor(self.actions),
        )


def masked_player(logits: Callable[[np.ndarray], np.ndarray]) -> Callable:
    """A policy acting in the env as the coordinator's `policy:FILE` allocator acts: every arm's choice features
    scored in one batch (`logits`: float32 rows to rows of logits), each arm taking its best valid action."""

    def act(env, obs: dict) -> dict:
        scores = logits(np.stack([obs[a] for a in env.agents]).astype(np.float32))
        return {a: masked_choice(row, env.action_mask(a)) for a, row in zip(env.agents, scores)}

    return act


def actor_player(actor: torch.nn.Module) -> Callable:
    """`masked_player` of an actor being trained (no file written yet)."""

    def logits(rows: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            return actor(torch.from_numpy(rows)).numpy()

    return masked_player(logits)


def label_episode(env, seed: int, teacher: str, player: Callable | None, into: Demonstrations) -> int:
    """Play one episode from `seed` (`player` acts; None: the teacher itself) and label every arm that has a choice
    with the teacher's action. Returns the parts the episode completed; the env is closed after."""
    allocator = make_allocator(teacher, env.scene)

    def labelled(env, obs: dict) -> dict:
        taught = allocator_actions(env.chooser, allocator, env._options)
        for arm in env.agents:
            mask = env.action_mask(arm)
            if mask.sum() > 1:  # asked: something to choose besides waiting
                into.add(obs[arm], mask, taught[arm])
        return taught if player is None else player(env, obs)

    return run_episode(env, seed, labelled)["completed"]


def fit_actor(actor: torch.nn.Module, demos: Demonstrations, epochs: int = 60, lr: float = 1e-3) -> float:
    """Fit `actor` (features -> logits; its parameters are the SB3 policy's) to `demos` by the masked cross-entropy.
    Returns the share of labels its best valid action now matches."""
    features, masks, actions = demos.tensors()
    optimiser = torch.optim.Adam(actor.parameters(), lr=lr)
    generator = torch.Generator().manual_seed(0)
    actor.train()
    for _ in range(epochs):
        for batch in torch.randperm(len(actions), generator=generator).split(256):
            logits = actor(features[batch]).masked_fill(~masks[batch], -1e9)
            loss = torch.nn.functional.cross_entropy(logits, actions[batch])
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
    actor.eval()
    with torch.no_grad():
        chosen = actor(features).masked_fill(~masks, -1e9).argmax(dim=1)
    return float((chosen == actions).float().mean())


def dagger(
    actor: torch.nn.Module,
    make_env: Callable,
    teacher: str,
    rounds: int,
    episodes: int,
    first_seed: int = 0,
    report: Callable[[str], None] = print,
) -> Demonstrations:
    """`rounds` rounds of `episodes` episodes each (seeds from `first_seed` on, none used twice): the teacher plays
    round 0, the actor every round after; the actor is fitted to all labels after each. Returns the labels."""
    demos = Demonstrations()
    seed = first_seed
    for round_ in range(rounds):
        player = None if round_ == 0 else actor_player(actor)
        parts = [label_episode(make_env(), seed + e, teacher, player, demos) for e in range(episodes)]
        seed += episodes
        accuracy = fit_actor(actor, demos)
        who = teacher if player is None else "policy"
        report(
            f"round {round_}: {who} played {np.mean(parts):.1f} parts an episode; {len(demos.actions)} labels, "
            f"the actor matches {accuracy:.0%}"
        )
    return demos
