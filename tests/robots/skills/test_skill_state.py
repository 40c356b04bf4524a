"""A skill's saved state: put back into a fresh skill of the same arm, it goes on exactly as the skill it came from."""

import numpy as np

from robots.saved_state import pack, unpack
from robots.skills.pick_place import Phase, PickPlaceSkill
from robots.skills.skill_state import SkillState, restore_skill, skill_state
from tests.robots.skills.test_grants import BASE, DT, SPEC, obs, part_at, started

BELT = (0.05, 0.0, 0.0)


def restored_copy(skill: PickPlaceSkill) -> PickPlaceSkill:
    """A fresh skill for the same arm, given `skill`'s state through its bytes."""
    fresh = PickPlaceSkill(SPEC, BASE, grants_required=True)
    restore_skill(fresh, unpack(pack(skill_state(skill)), SkillState))
    return fresh


def test_a_fresh_skill_saves_and_comes_back():
    skill = PickPlaceSkill(SPEC, BASE, grants_required=True)
    assert pack(skill_state(restored_copy(skill))) == pack(skill_state(skill))


def test_a_skill_restored_mid_task_goes_on_exactly_as_the_one_saved():
    skill = started(BELT)
    q = np.asarray(SPEC.home_q, float)
    copies = []
    for k in range(400):  # through the grant, the approach, the grasp and on
        t = k * DT
        if skill.request is not None and k % 7 == 0:
            skill.on_grant(skill.request.seq, "grant", "", t)
        if k in (0, 30, 90, 160):
            copies.append((k, restored_copy(skill)))
        goals = skill.step(obs(q, t), {7: part_at(0.0, t, BELT)})
        for start_k, copy in copies:
            if copy.request is not None and k % 7 == 0:
                copy.on_grant(copy.request.seq, "grant", "", t)
            assert copy.step(obs(q, t), {7: part_at(0.0, t, BELT)}) == goals, f"the copy from step {start_k}"
        assert all(pack(skill_state(c)) == pack(skill_state(skill)) for _, c in copies)
    assert skill.phase not in (Phase.IDLE, Phase.APPROACH), "the skill got past its approach"
