"""`docs/ros2.md` gives a ROS 2 user every type hash the line's keys end in, and they are the code's."""

import re
from pathlib import Path

from fleet.ros import names
from fleet.ros.rmw_zenoh import type_hash

DOCS = Path(__file__).parents[3] / "docs" / "ros2.md"


def test_the_docs_give_every_type_hash_of_the_line_s_graph_as_the_code_makes_it():
    table = dict(re.findall(r"^\| `([a-z_0-9/A-Z]+)` \| `(RIHS01_[0-9a-f]{64})` \|$", DOCS.read_text(), re.MULTILINE))
    used = {*names.TOPIC_TYPES.values(), "sensor_msgs/msg/JointState", "trajectory_msgs/msg/JointTrajectory"}
    used |= set(names.SERVICE_TYPES.values()) | {"action_msgs/srv/CancelGoal", "action_msgs/msg/GoalStatusArray"}
    for action in (names.FOLLOW_JOINT_TRAJECTORY, names.GRIPPER_COMMAND):
        used |= {f"{action}_SendGoal", f"{action}_GetResult", f"{action}_FeedbackMessage"}
    assert used <= set(table), sorted(used - set(table))
    assert {t: type_hash(t) for t in table} == table
