"""A policy trained in the env's allocate mode runs the real line: what it observes there (`observe="choices"`) is what
the coordinator's `policy:FILE` allocator builds from the dispatcher's view, so in every state it chooses the same."""

import numpy as np
import pytest

from coordinator.choice_slots import CHOICE_FEATURES, chosen_pairs, masked_choice
from coordinator.policy_allocator import PolicyAllocator
from coordinator.policy_file import load_policy
from fleet.env import parallel_env
from tests.coordinator.choice_policies import policy_file


def test_in_every_state_the_coordinators_policy_allocator_chooses_as_the_policy_does_in_the_env(tmp_path):
    policy = load_policy(policy_file(tmp_path, seed=1))
    env = parallel_env(
        scene="mixed_infeed",
        scenario="line",
        action_mode="allocate",
        observe="choices",
        choice_steps=True,
        max_cycles=400,
        control_hz=10,
    )
    allocator = PolicyAllocator(env.scene, policy)
    obs, _ = env.reset(seed=2)
    assert env.observation_space(env.agents[0]).shape == (CHOICE_FEATURES,)
    states = took = 0
    while env.agents:
        chooser = env.chooser
        tasks = chooser.dispatcher.candidates(chooser.pending())
        choices, features = allocator.observe(tasks, chooser.arm_views(), chooser.parts(), chooser.busy_stations())
        for arm, row in features.items():
            np.testing.assert_array_equal(row, obs[arm], err_msg=f"{arm} sees its choices as the env shows them")
        assert set(features) == {a for a in env.agents if env.action_mask(a)[1:].any()}
        actions = {a: masked_choice(policy.logits(obs[a][None])[0], env.action_mask(a)) for a in env.agents}
        pairs = allocator.allocate(tasks, chooser.arm_views(), chooser.parts(), chooser.busy_stations())
        assert pairs == chosen_pairs(actions, chooser.arm_choices)
        states += bool(features)
        obs, _, _, _, infos = env.step(actions)
        took += sum(infos[a]["choice"] == "took" for a in infos)
        assert {a for a in infos if infos[a]["choice"] == "took"} == {arm for _, arm in pairs}
    assert states >= 10 and took >= 5, (states, took)
    env.close()


def test_observing_only_choices_is_refused_outside_allocate_mode():
    with pytest.raises(ValueError, match="observe='choices' applies to action_mode 'allocate'"):
        parallel_env(scenario="reach", n_arms=2, observe="choices")
    with pytest.raises(ValueError, match="observe 'joints' is not available; valid: cell, choices"):
        parallel_env(scenario="line", action_mode="allocate", n_arms=2, observe="joints")
