"""MoveIt's controllers file for a scene: one FollowJointTrajectory controller per arm, on the action the line
serves, with the joint names `/joint_states` carries."""

import subprocess
import sys

import yaml

from fleet.common.scene_loading import load_checked_scene
from fleet.ros import names
from robots.registry import get_robot


def test_the_controllers_file_names_every_arms_action_and_joints(tmp_path):
    out = tmp_path / "moveit_controllers.yaml"
    done = subprocess.run(
        [sys.executable, "-m", "fleet", "ros2", "controllers", "sorting_line", "--arms", "3", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    manager = yaml.safe_load(out.read_text())["moveit_simple_controller_manager"]
    scene = load_checked_scene("sorting_line", arms=3)
    served = names.line_actions([a.name for a in scene.arms])
    assert manager["controller_names"] == [a.name for a in scene.arms]
    for arm in scene.arms:
        controller = manager[arm.name]
        assert served[f"/{arm.name}/{controller['action_ns']}"] == names.FOLLOW_JOINT_TRAJECTORY
        assert controller["joints"] == [f"{arm.name}/{j}" for j in get_robot(arm.model).arm_joints]
