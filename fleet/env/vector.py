"""Many independent cells at once: SuperSuit's vector env over the PettingZoo env, in worker processes.

`vector_env(n_cells, num_cpus, **env_kwargs)` is a Gymnasium vector env whose rows are every
agent of every cell (cell 0's arms, then cell 1's, ...), as parameter-sharing learners
(Stable-Baselines3, CleanRL) expect. `reset(seed=s)` seeds cell i with `s + i`, so each cell
repeats the single env of that seed. Needs the `rl` extra (supersuit).
"""

from __future__ import annotations

import os

from fleet.env.cell_env import CellParallelEnv


def vector_env(n_cells: int, num_cpus: int | None = None, **env_kwargs):
    """`n_cells` cells of `parallel_env(**env_kwargs)` as one vector env, in `num_cpus` worker processes
    (default: as many as cores, at most one per cell; 0 runs them in this process)."""
    try:
        import supersuit
    except ImportError as exc:
        raise ImportError("vector_env needs supersuit: pip install 'clawfleet[rl]'") from exc
    if n_cells < 1:
        raise ValueError(f"n_cells {n_cells}: at least one cell")
    cpus = min(n_cells, os.cpu_count() or 1) if num_cpus is None else num_cpus
    cell = supersuit.pettingzoo_env_to_vec_env_v1(CellParallelEnv(**env_kwargs))
    return supersuit.concat_vec_envs_v1(cell, n_cells, num_cpus=cpus, base_class="gymnasium")
