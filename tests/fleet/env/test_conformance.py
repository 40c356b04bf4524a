"""The PettingZoo env passes PettingZoo's own conformance tests, unmodified, and repeats for a seed."""

import numpy as np
import pytest
from pettingzoo.test import max_cycles_test

import fleet.env
from fleet.env import conformance, parallel_env


@pytest.mark.parametrize(("scenario", "mode"), conformance.CONFIGURATIONS)
def test_pettingzoo_parallel_aec_seed_and_max_cycles_tests_pass(scenario, mode):
    conformance.check(scenario, mode)


@pytest.mark.parametrize("scenario", ["line", "handover"])
def test_allocate_mode_with_the_action_mask_in_the_observation_passes_them_too(scenario):
    conformance.check(scenario, "allocate", mask_in_observation=True)


@pytest.mark.parametrize("scenario", ["line", "handover"])
def test_choice_stepping_passes_them_too(scenario):
    conformance.check(scenario, "allocate", choice_steps=True, mask_in_observation=True)


def test_ee_delta_moves_the_claw_the_way_it_is_told():
    penv = parallel_env(n_arms=1, max_cycles=100, action_mode="ee_delta")
    penv.reset(seed=0)
    start = penv.observer.tools()["arm_0"]
    up = np.array([0.0, 0.0, 1.0, 1.0], np.float32)  # claw up at full speed, gripper open
    for _ in range(10):
        penv.step({"arm_0": up})
    moved = penv.observer.tools()["arm_0"] - start
    assert moved[2] > 0.06  # about 10 steps x 1 cm, less the drives' lag
    assert np.linalg.norm(moved[:2]) < 0.02


def test_max_cycles():
    max_cycles_test(fleet.env)


def test_agents_are_the_arm_ids_and_a_seed_repeats_an_episode():
    a, b = parallel_env(n_arms=3, max_cycles=30), parallel_env(n_arms=3, max_cycles=30)
    assert a.possible_agents == ["arm_0", "arm_1", "arm_2"]
    rng = np.random.default_rng(1)
    obs_a, _ = a.reset(seed=7)
    obs_b, _ = b.reset(seed=7)
    while a.agents:
        actions = {x: rng.uniform(-1, 1, a.action_space(x).shape).astype(np.float32) for x in a.agents}
        obs_a, rew_a, *_ = a.step(actions)
        obs_b, rew_b, *_ = b.step(actions)
        assert all(np.array_equal(obs_a[x], obs_b[x]) for x in obs_a) and rew_a == rew_b
    assert a.state().shape == b.state().shape


def test_unknown_options_are_refused_with_the_valid_ones():
    with pytest.raises(ValueError, match="valid: reach, pick_place, handover, line"):
        parallel_env(scenario="juggle")
    with pytest.raises(ValueError, match="valid with 'allocate': handover, line"):
        parallel_env(scenario="reach", action_mode="allocate")
    with pytest.raises(ValueError, match="exactly 2 arms"):
        parallel_env(scenario="handover", scene="sorting_line", n_arms=3)
