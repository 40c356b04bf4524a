"""Small choice policies for tests: real torch modules, written as policy files as a trainer writes them."""

from __future__ import annotations

from pathlib import Path

import torch

from coordinator.choice_slots import CHOICE_FEATURES, SLOTS
from coordinator.policy_file import save_policy


def random_policy(seed: int = 0, wait_bias: float = -2.0) -> torch.nn.Module:
    """An untrained MLP (seeded): its choices among the slots vary with the features; waiting is made unlikely, so a
    line run with it takes work."""
    torch.manual_seed(seed)
    module = torch.nn.Sequential(torch.nn.Linear(CHOICE_FEATURES, 16), torch.nn.Tanh(), torch.nn.Linear(16, SLOTS + 1))
    with torch.no_grad():
        module[2].bias[0] += wait_bias
    return module


def policy_file(folder: Path, seed: int = 0) -> Path:
    """`random_policy(seed)` saved as a policy file in `folder`."""
    return save_policy(random_policy(seed), folder / f"random_{seed}.pt2", trained_on=f"untrained, seed {seed}")
