"""One ROS name scheme for a line, the same for every ROS front end (and for the recordings' topics).

Arm ids are ROS namespaces: `/<arm>/joint_states`, `/<arm>/follow_joint_trajectory`. Types are ROS 2 names
(`sensor_msgs/msg/JointState`).
"""

from __future__ import annotations

JOINT_STATES = "/joint_states"  # every arm's joints, names prefixed `<arm>/`
TF, TF_STATIC, CLOCK = "/tf", "/tf_static", "/clock"
CELL, PARTS = "/cell", "/parts"  # markers: the belt and stations once, the parts as they go
ROSOUT = "/rosout"  # the line's log: arms lost, held, taken; goals refused (`fleet.ros.line_log`)

TOPIC_TYPES = {
    JOINT_STATES: "sensor_msgs/msg/JointState",
    TF: "tf2_msgs/msg/TFMessage",
    TF_STATIC: "tf2_msgs/msg/TFMessage",
    CLOCK: "rosgraph_msgs/msg/Clock",
    CELL: "visualization_msgs/msg/MarkerArray",
    PARTS: "visualization_msgs/msg/MarkerArray",
    ROSOUT: "rcl_interfaces/msg/Log",
}
LATCHED = (TF_STATIC, CELL)  # TRANSIENT_LOCAL: a late subscriber gets the last message at once

DEFAULT_MAX_RATE_HZ = 50.0  # wall: topics from the line's view and states at most this often (a lockstep line is fast)

FOLLOW_JOINT_TRAJECTORY = "control_msgs/action/FollowJointTrajectory"
GRIPPER_COMMAND = "control_msgs/action/GripperCommand"
ESTOP, PAUSE, RESUME = "/estop", "/pause", "/resume"
SERVICE_TYPES = {ESTOP: "std_srvs/srv/SetBool", PAUSE: "std_srvs/srv/Trigger", RESUME: "std_srvs/srv/Trigger"}


def arm_joint_states(arm: str) -> str:
    return f"/{arm}/joint_states"


def arm_trajectory_action(arm: str) -> str:
    """The arm's `FollowJointTrajectory` action, as ros2_controllers' joint trajectory controller names it."""
    return f"/{arm}/follow_joint_trajectory"


def arm_gripper_action(arm: str) -> str:
    return f"/{arm}/gripper_cmd"


def line_topics(arms: list[str]) -> dict[str, str]:
    """Every topic a line serves and its type."""
    return TOPIC_TYPES | {arm_joint_states(a): "sensor_msgs/msg/JointState" for a in arms}


def line_actions(arms: list[str]) -> dict[str, str]:
    """Every action a line serves and its type."""
    out = {arm_trajectory_action(a): FOLLOW_JOINT_TRAJECTORY for a in arms}
    return out | {arm_gripper_action(a): GRIPPER_COMMAND for a in arms}


def action_arm(action: str) -> str:
    """The arm an action of `line_actions` drives (`/arm_0/follow_joint_trajectory` -> `arm_0`)."""
    return action.strip("/").split("/")[0]
