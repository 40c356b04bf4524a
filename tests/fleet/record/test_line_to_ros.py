"""The ROS messages of a line, built without a run: TF split as robot_state_publisher splits it (fixed joints on
`/tf_static`, moving ones on `/tf`), composing to Pinocchio's own tool pose."""

import numpy as np

from fleet.bus.messages import ArmState
from fleet.common.scene_loading import load_checked_scene
from fleet.record.line_to_ros import LineToRos
from tests.fleet.record.tf_tree import up_to_root


def an_arm_state(arm: str, q: list[float], sim_time_s: float) -> ArmState:
    return ArmState(
        arm=arm,
        tick=10,
        sim_time_s=sim_time_s,
        q=q,
        dq=[0.0] * 6,
        gripper_q=[0.01, 0.01],
        tool_position=[0.0] * 3,
        tool_quaternion_wxyz=[1.0, 0.0, 0.0, 0.0],
    )


def test_fixed_links_are_static_and_moving_links_compose_to_the_tool_pose():
    ros = LineToRos(load_checked_scene("assembly_line"))
    arm = ros.arms["arm_0"]
    static = {t.child_frame_id: t for t in ros.tf_static().transforms}
    assert "arm_0/tool_link" in static and static["arm_0/tool_link"].header.frame_id == "arm_0/palm_link"
    assert "arm_0/base_link" in static and static["arm_0/base_link"].header.frame_id == "world"

    q = [0.3, -0.4, 0.9, 0.2, -0.5, 0.7]
    state = an_arm_state("arm_0", q, 1.25)
    moving = {t.child_frame_id: t for t in ros.tf([state]).transforms}
    assert not set(moving) & set(static), "a link is either on /tf or on /tf_static"
    assert all(t.header.stamp.sec == 1 and t.header.stamp.nanosec == 250_000_000 for t in moving.values())

    root, world_from_tool = up_to_root("arm_0/tool_link", moving | static)
    assert root == "world"
    base_from_tool = arm.kin.frame_pose(arm.kin.full_q(np.array(q), np.array([0.01, 0.01])))
    np.testing.assert_allclose(world_from_tool, arm.base_to_world @ base_from_tool, atol=1e-9)
