"""Continuous actions on a cell of three robot models: each arm's joint targets move by its own action,
translated with its model's rows (`ActionTranslator` per model), and an arm that does not act holds."""

import numpy as np

from fleet.env.cell_env import CellParallelEnv
from robots.policy_actions import MAX_DELTA_RAD


def test_each_model_s_arms_move_by_their_own_actions_and_a_silent_arm_holds():
    env = CellParallelEnv(scene="mixed_fleet", scenario="reach", max_cycles=5)
    try:
        env.reset(seed=3)
        models = {env.world.arms[a].spec.uid for a in env.possible_agents}
        assert len(models) == 3
        before = {a: env.joint_targets(a).copy() for a in env.possible_agents}
        rng = np.random.default_rng(3)
        acting = env.possible_agents[:2]
        actions = {a: rng.uniform(-0.5, 0.5, env.action_space(a).shape).astype(np.float32) for a in acting}
        env.step(actions)
        for a in acting:
            translator = env.joint_actions.translators[env.world.arms[a].spec.uid]  # one per robot model
            expected = np.clip(before[a] + MAX_DELTA_RAD * actions[a][:-1], translator.lower, translator.upper)
            np.testing.assert_allclose(env.joint_targets(a), expected, atol=1e-6)
        silent = env.possible_agents[2]
        np.testing.assert_allclose(env.joint_targets(silent), before[silent])
    finally:
        env.close()
