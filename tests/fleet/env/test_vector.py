"""Many cells at once (SuperSuit's vector env in worker processes): cell i of a vector seeded s runs exactly as a
single env seeded s + i, and closing it leaves no worker behind."""

import multiprocessing

import numpy as np
import pytest

from fleet.env import parallel_env

pytest.importorskip("supersuit", reason="the rl extra (supersuit) is not installed")

from fleet.env.vector import vector_env  # noqa: E402

SETTINGS = dict(scenario="reach", n_arms=2, max_cycles=30)


def test_each_cell_of_a_vector_runs_as_the_single_env_of_its_seed_and_closing_frees_the_workers():
    venv = vector_env(2, num_cpus=2, **SETTINGS)
    try:
        obs, _ = venv.reset(seed=5)
        singles = [parallel_env(**SETTINGS) for _ in range(2)]
        single_obs = [env.reset(seed=5 + i)[0] for i, env in enumerate(singles)]
        rows = lambda per_cell: np.concatenate([np.stack([o[a] for a in ("arm_0", "arm_1")]) for o in per_cell])  # noqa: E731
        assert obs.shape == (4, singles[0].observation_space("arm_0").shape[0])
        assert np.array_equal(obs, rows(single_obs)), "rows are cell 0's arms, then cell 1's"
        rng = np.random.default_rng(0)
        for _ in range(SETTINGS["max_cycles"] - 1):
            actions = rng.uniform(-1, 1, (4, *venv.action_space.shape)).astype(np.float32)
            obs, rewards, *_ = venv.step(actions)
            stepped = [
                env.step({a: actions[2 * i + j] for j, a in enumerate(("arm_0", "arm_1"))})
                for i, env in enumerate(singles)
            ]
            assert np.allclose(obs, rows([s[0] for s in stepped]))
            assert np.allclose(rewards, [s[1][a] for s in stepped for a in ("arm_0", "arm_1")])
        assert len(multiprocessing.active_children()) >= 2, "the cells ran in worker processes"
    finally:
        venv.close()
    assert multiprocessing.active_children() == []


def test_a_vector_needs_at_least_one_cell():
    with pytest.raises(ValueError, match="at least one cell"):
        vector_env(0, **SETTINGS)
