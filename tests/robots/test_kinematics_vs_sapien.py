"""Pinocchio's link poses equal SAPIEN's for every registered model (100 random configurations each)."""

import numpy as np
import pinocchio as pin
import pytest
import sapien

from fleet.physics.arm import SimArm, yaw_pose
from robots.kinematics import KinematicModel
from robots.registry import get_robot, robot_names

TOL = 1e-5


@pytest.mark.parametrize("uid", robot_names())
def test_link_poses_match_sapien(uid):
    spec = get_robot(uid)
    scene = sapien.Scene([sapien.physx.PhysxCpuSystem()])
    base = yaw_pose((0.2, -0.1, 0.05), 0.7)
    arm = SimArm(scene, spec, "arm_0", base, 0)
    km = KinematicModel(spec)
    base_to_world = base.to_transformation_matrix()
    rng = np.random.default_rng(42)
    worst_m = worst_rot = 0.0
    for _ in range(100):
        q = rng.uniform(km.lower, km.upper)
        arm.set_qpos(q[np.concatenate([km.arm_q_index, km.gripper_q_index])])
        poses = km.link_poses(q)
        assert set(arm.links) <= set(poses), "every SAPIEN link has a Pinocchio frame"
        for name, link in arm.links.items():
            expected = base_to_world @ poses[name]
            got = link.entity_pose.to_transformation_matrix()
            worst_m = max(worst_m, np.abs(expected[:3, 3] - got[:3, 3]).max())
            rel = expected[:3, :3].T @ got[:3, :3]
            worst_rot = max(worst_rot, float(np.linalg.norm(pin.log3(rel))))
    assert worst_m < TOL, f"{uid}: position differs by {worst_m:.2e} m"
    assert worst_rot < TOL, f"{uid}: orientation differs by {worst_rot:.2e} rad"
