"""`fleet bench env`: agent-steps per second of the PettingZoo env, and its step time against raw physics.

Random actions; the raw-physics column steps the same world for the same number
of control ticks with the arms' targets set once, no observations or rewards.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from fleet.env.cell_env import CellParallelEnv


@dataclass(frozen=True)
class EnvRow:
    arms: int
    task: str
    steps: int
    env_s: float
    physics_s: float

    @property
    def agent_steps_per_s(self) -> float:
        return self.steps * self.arms / self.env_s

    @property
    def ratio_to_physics(self) -> float:
        return self.env_s / self.physics_s


def bench_env(arms: int, task: str = "reach", steps: int = 400, seed: int = 0, distributed: bool = False) -> EnvRow:
    """Random joint_delta actions at 20 Hz; then the same world stepped for as many ticks with nothing else."""
    env = CellParallelEnv(n_arms=arms, task=task, max_cycles=steps, distributed=distributed)
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    actions = [{a: rng.uniform(-1, 1, env.action_space(a).shape).astype(np.float32) for a in env.possible_agents} for _ in range(steps)]
    start = time.perf_counter()
    for act in actions:
        env.step(act)
    env_s = time.perf_counter() - start
    env.reset(seed=seed)
    start = time.perf_counter()
    env.world.step(steps)
    physics_s = time.perf_counter() - start
    env.close()
    return EnvRow(arms, task, steps, env_s, physics_s)
