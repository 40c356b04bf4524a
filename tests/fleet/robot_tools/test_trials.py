"""A physical pick: the part ends in the bin, carried only by friction between the fingers, for each robot in the
trial cell it is fed (parts its gripper spans; turned where its first joint cannot reach belt and bin)."""

import math

import numpy as np
import pytest

from fleet.robot_tools.trials import graspable, run_trial, trial_scene
from fleet.robot_tools.tuning import Candidate, candidates, search
from robots.registry import get_robot, is_available
from robots.skills.pick_place import PickPlaceTiming


def test_a_few_seeded_openclaw_picks_succeed():
    results = [run_trial("openclaw", seed) for seed in range(3)]
    assert all(r.success for r in results), results


@pytest.mark.skipif(not is_available("so101"), reason="needs the models extra")
def test_the_so101_picks_with_a_tilted_claw_where_it_cannot_point_straight_down():
    results = [run_trial("so101", seed) for seed in range(4)]
    assert sum(r.success for r in results) >= 3, results  # 99 of 100 in docs/benchmarks.md; none at first
    scene = trial_scene("so101", 0)
    assert scene.arms[0].base.yaw_deg != 90.0  # its +-110 degree base joint would not turn from belt to bin


@pytest.mark.skipif(not is_available("so101"), reason="needs the models extra")
def test_the_trial_cell_feeds_each_robot_the_parts_its_gripper_spans():
    spec = get_robot("so101")
    parts = trial_scene("so101", 0).feeders[0].parts
    assert parts == graspable(spec, parts) and all(min(p.size_m[:2]) <= spec.grasp_width_m[1] for p in parts)
    assert len(trial_scene("openclaw", 0).feeders[0].parts) == 6  # every bundled part fits the OpenClaw's claw


def test_the_tuning_search_starts_from_the_registered_robot_and_draws_distinct_settings():
    drawn = candidates(6, seed=3)
    assert drawn[0] == Candidate() and len(set(drawn)) == 6 and drawn == candidates(6, seed=3)
    tuned = drawn[1].spec_for(get_robot("openclaw"), "openclaw_tuned")
    assert math.isclose(
        tuned.arm_gains.stiffness, get_robot("openclaw").arm_gains.stiffness * drawn[1].arm_stiffness_scale
    )
    timing = PickPlaceTiming.for_robot(tuned)  # the heights searched reach the pick skill
    assert (timing.hover_m, timing.lift_m, timing.pregrasp_clearance_m) == (
        drawn[1].hover_m,
        drawn[1].lift_m,
        drawn[1].pregrasp_clearance_m,
    )
    assert drawn[1].describe(get_robot("openclaw"))["hover_m"] == drawn[1].hover_m
    results = search("openclaw", 2, 1, seed=0)
    assert len(results) == 2 and results[0].rank_key <= results[1].rank_key
    assert search("openclaw", 2, 1, seed=0, jobs=2) == results  # settings tried at once, in processes of their own


def test_a_search_may_vary_only_some_values_and_tries_each_setting_of_them_once():
    heights = candidates(100, seed=0, vary=["hover_m", "lift_m"])
    assert len(heights) == 1 + 4 * 3 and len(set(heights)) == len(heights)
    assert all(c.approach_speed is None and c.arm_stiffness_scale == 1.0 for c in heights)
    with pytest.raises(ValueError, match="cannot vary hover; valid values: arm_stiffness_scale"):
        candidates(5, seed=0, vary=["hover"])


@pytest.mark.skipif(not is_available("so101"), reason="needs the models extra")
def test_a_fixed_jaw_comes_down_its_gap_clear_of_the_part_and_the_pads_friction_is_searched():
    spec = get_robot("so101")
    touching = np.asarray(spec.grasp_centre_tool(0.04))
    clear = np.asarray(spec.grasp_centre_tool(0.04, fixed_jaw_gap_m=0.004))
    # the part is aimed 4 mm further from the fixed jaw, along the way the moving jaw closes
    assert np.allclose(touching - clear, 0.004 * np.asarray(spec.closing_axis_tool))
    assert get_robot("openclaw").grasp_centre_tool(0.04, 0.004) == (0.0, 0.0, 0.0)  # two moving jaws: centred
    setting = Candidate(fixed_jaw_gap_m=0.006, finger_friction=2.0)
    tuned = setting.spec_for(spec, "so101_gap")
    assert PickPlaceTiming.for_robot(tuned).fixed_jaw_gap_m == 0.006 and tuned.finger_friction == 2.0
    assert setting.describe(spec)["finger_friction"] == 2.0
    assert Candidate().spec_for(spec, "so101_same").finger_friction == spec.finger_friction


@pytest.mark.skipif(not is_available("panda"), reason="needs the models extra")
def test_a_few_seeded_panda_picks_succeed_with_its_own_natural_yaw():
    results = [run_trial("panda", seed) for seed in range(3)]
    assert all(r.success for r in results), results  # 100 of 100 in docs/benchmarks.md; 16 of 20 before
