"""IK converges on reachable targets, reports failure with a residual on unreachable ones."""

import numpy as np
import pytest

from robots.frames import top_down_rotation, transform
from robots.ik import solve_ik
from robots.kinematics import KinematicModel
from robots.registry import get_robot, robot_names


@pytest.mark.parametrize("uid", robot_names())
def test_ik_reaches_poses_of_random_configurations(uid):
    spec = get_robot(uid)
    km = KinematicModel(spec)
    rng = np.random.default_rng(3)
    start = km.full_q(np.array(spec.home_q))
    solved = 0
    for _ in range(20):
        q_goal = km.full_q(rng.uniform(km.lower[km.arm_q_index], km.upper[km.arm_q_index]))
        target = km.frame_pose(q_goal)
        result = solve_ik(km, target, start, approach_axis_only=spec.arm_dof < 6)
        if result.success:
            solved += 1
            reached = km.frame_pose(result.q)
            assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 1e-3
            assert np.all(result.q >= km.lower - 1e-9) and np.all(result.q <= km.upper + 1e-9)
        else:
            assert result.position_error_m > 0 or result.angle_error_rad > 0
    assert solved >= 17


def test_ik_reports_an_unreachable_target_with_its_residual():
    km = KinematicModel(get_robot("openclaw"))
    far = transform(np.array([2.0, 0.0, 0.3]), top_down_rotation(0.0))
    result = solve_ik(km, far, km.full_q(np.array(km.spec.home_q)))
    assert not result.success
    assert result.position_error_m > 1.0


def test_position_and_approach_axis_leaves_roll_free():
    km = KinematicModel(get_robot("openclaw"))
    target = transform(np.array([0.35, 0.05, 0.15]), top_down_rotation(1.0))
    result = solve_ik(km, target, km.full_q(np.array(km.spec.home_q)), approach_axis_only=True)
    assert result.success
    pose = km.frame_pose(result.q)
    np.testing.assert_allclose(pose[:3, 3], target[:3, 3], atol=1e-3)
    np.testing.assert_allclose(pose[:3, 2], [0, 0, -1], atol=2e-3)


def test_frame_jacobian_matches_finite_differences():
    km = KinematicModel(get_robot("openclaw"))
    q = km.full_q(np.array([0.3, -0.4, 1.2, 0.5, 0.8, -0.2]))
    jac = km.frame_jacobian(q)
    eps = 1e-6
    for i in km.arm_q_index:
        dq = np.zeros(km.nq)
        dq[i] = eps
        fd = (km.frame_pose(q + dq)[:3, 3] - km.frame_pose(q - dq)[:3, 3]) / (2 * eps)
        np.testing.assert_allclose(jac[:3, i], fd, atol=1e-6)
