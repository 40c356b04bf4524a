"""World poses of fixed frames on an arm's links from one Pinocchio pass (`PlacedFrames`), and arms' actions
translated a row per arm (`ActionTranslator`): both equal the one-at-a-time computation they replace."""

import numpy as np
import pytest

from robots.frames import yaw_transform
from robots.kinematics import KinematicModel, PlacedFrames
from robots.policy_actions import CONTINUOUS_MODES, ActionTranslator
from robots.registry import get_robot, robot_names


def _offset(rng: np.random.Generator) -> np.ndarray:
    transform = yaw_transform(tuple(rng.uniform(-0.3, 0.3, 3)), float(rng.uniform(-3, 3)))
    transform[:3, 3] += rng.uniform(-0.05, 0.05, 3)
    return transform


@pytest.mark.parametrize("uid", robot_names())
def test_placed_frames_are_base_times_link_times_offset_on_every_link_root_included(uid):
    spec = get_robot(uid)
    km = KinematicModel(spec)
    rng = np.random.default_rng(0)
    base = yaw_transform((0.4, -0.2, 0.1), 0.7)
    links = list(km.link_poses(km.full_q(np.asarray(spec.home_q, float))))
    assert any(km.model.frames[km.frame_id(link)].parentJoint == 0 for link in links)  # a link fixed to the root too
    frames = [(link, _offset(rng)) for link in links]
    placed = PlacedFrames(km, base, frames)
    lower, upper = km.lower[km.arm_q_index], km.upper[km.arm_q_index]
    for _ in range(5):
        q = km.full_q(rng.uniform(lower, upper))
        expected = [base @ km.link_poses(q)[link] @ offset for link, offset in frames]
        np.testing.assert_allclose(placed.poses(q), expected, atol=1e-12)


@pytest.mark.parametrize("mode", CONTINUOUS_MODES)
def test_a_row_per_arm_translates_as_one_translator_per_arm(mode):
    spec = get_robot("so101")
    rng = np.random.default_rng(1)
    bases = [yaw_transform((0.5 * i, 0.0, 0.0), 0.4 * i) for i in range(3)]
    rows = ActionTranslator(spec, bases, mode)
    singles = [ActionTranslator(spec, b, mode) for b in bases]
    start = np.array([spec.home_q] * 3, float) + rng.uniform(-0.2, 0.2, (3, spec.arm_dof))
    rows.reset(start)
    for single, q in zip(singles, start):
        single.reset(q)
    for _ in range(20):
        actions = rng.uniform(-1.5, 1.5, (3, rows.action_size))  # beyond [-1, 1]: clipped
        q, opening = rows.apply(actions)
        for i, single in enumerate(singles):
            q_one, opening_one = single.apply(actions[i])
            np.testing.assert_allclose(q[i], q_one[0], atol=1e-12)
            assert opening[i] == pytest.approx(opening_one[0])
        np.testing.assert_array_equal(rows.at_limit(q), [single.at_limit(single.q_target)[0] for single in singles])


def test_a_wrong_action_size_is_refused_with_the_size_expected():
    rows = ActionTranslator(get_robot("so101"), [np.eye(4), np.eye(4)], "joint_delta")
    with pytest.raises(ValueError, match="6 entries"):  # 5 joints and the gripper
        rows.apply(np.zeros((2, 5)))
    with pytest.raises(ValueError, match="one row per arm, 2 here"):
        rows.apply(np.zeros(6))
