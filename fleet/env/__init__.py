"""clawfleet as a PettingZoo environment: `parallel_env(**kwargs)`, `env(**kwargs)` (AEC) and `raw_env`.

from fleet.env import parallel_env
env = parallel_env(scene="sorting_line", n_arms=2, scenario="reach", max_cycles=200)
observations, infos = env.reset(seed=0)
"""

from __future__ import annotations

from pettingzoo.utils import wrappers
from pettingzoo.utils.conversions import parallel_to_aec

from fleet.env.cell_env import CellParallelEnv


def parallel_env(**kwargs) -> CellParallelEnv:
    return CellParallelEnv(**kwargs)


def raw_env(**kwargs):
    """The AEC version, through PettingZoo's own conversion."""
    return parallel_to_aec(CellParallelEnv(**kwargs))


def env(**kwargs):
    """The AEC version with PettingZoo's order-enforcing wrapper."""
    return wrappers.OrderEnforcingWrapper(raw_env(**kwargs))
