"""What MoveIt needs to drive a line's arms through its ROS front ends: `moveit_controllers.yaml` for
moveit_simple_controller_manager, one `FollowJointTrajectory` controller per arm, named by the arm id, so MoveIt
sends to `/<arm>/follow_joint_trajectory` with the joint names `/joint_states` carries (`<arm>/<joint>`)."""

from __future__ import annotations

import yaml

from fleet.ros import names
from robots.registry import get_robot
from scenes.schema import Scene


def moveit_controllers(scene: Scene) -> dict:
    """The controllers file's content for `scene`."""
    arms = [a.name for a in scene.arms]
    out: dict = {"controller_names": arms}
    for a in scene.arms:
        action = names.arm_trajectory_action(a.name)
        out[a.name] = {
            "type": "FollowJointTrajectory",
            "action_ns": action.rsplit("/", 1)[1],
            "default": True,
            "joints": [f"{a.name}/{j}" for j in get_robot(a.model).arm_joints],
        }
    return {
        "moveit_controller_manager": "moveit_simple_controller_manager/MoveItSimpleControllerManager",
        "moveit_simple_controller_manager": out,
    }


def moveit_controllers_yaml(scene: Scene) -> str:
    header = (
        f"# MoveIt controllers of clawfleet scene {scene.name!r}: one FollowJointTrajectory per arm (docs/ros2.md)\n"
    )
    return header + yaml.safe_dump(moveit_controllers(scene), sort_keys=False)
