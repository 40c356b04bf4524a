"""The services and actions clawfleet registers hash as ROS 2 Jazzy's do: values published by rmw_zenoh's design
document and by other ROS 2 implementations (for the service and action types rosidl builds from `.srv` and
`.action` files)."""

import numpy as np
import pytest

from fleet.record.ros_types import TYPESTORE
from fleet.ros.ros_interfaces import register_action, register_interfaces, register_service
from fleet.ros.ros_json import from_json, to_json

PUBLISHED = {  # Jazzy
    "std_srvs/srv/SetBool": "abe9e4bb6b41b40e6789712c00ec8871923e089af3f667a79992a428cff2da0a",
    "std_srvs/srv/Trigger": "eeff2cd6fa5ad9d27cdf4dec64818317839b62f212a91e6b5304b634b2062c5f",
    "action_msgs/srv/CancelGoal": "573d8b0a534451d7bc2ac8c5ffde8ac14b8593b7001175d0cd6516dcbeb8689a",
    "action_msgs/msg/GoalStatusArray": "6c1684b00f177d37438febe6e709fc4e2b0d4248dca4854946f9ed8b30cda83e",
    "example_interfaces/srv/AddTwoInts": "e118de6bf5eeb66a2491b5bda11202e7b68f198d6f67922cf30364858239c81a",
    "action_tutorials_interfaces/action/Fibonacci_SendGoal": (
        "a0603060ed69fe2dfbd1a6f3b982a1749957ef346e4a4d2b311a05e305ec37bb"
    ),
    "action_tutorials_interfaces/action/Fibonacci_GetResult": (
        "8b47e383f1e31f6d8df6417ab54957e7d5ea24dad315646ad711ac3fdea81d58"
    ),
    "action_tutorials_interfaces/action/Fibonacci_FeedbackMessage": (
        "50fc26b9cac313652ecbeab3adf9b5414d59fd4d4d5f9058ddcc7525169927f1"
    ),
}


@pytest.fixture(scope="module", autouse=True)
def registered():
    register_interfaces()
    register_service("example_interfaces/srv/AddTwoInts", "int64 a\nint64 b", "int64 sum")
    fibonacci = "action_tutorials_interfaces/action/Fibonacci"
    register_action(fibonacci, "int32 order", "int32[] sequence", "int32[] partial_sequence")


@pytest.mark.parametrize("typename", sorted(PUBLISHED))
def test_services_and_actions_hash_as_ros_2_jazzys(typename):
    assert TYPESTORE.hash_rihs01(typename) == f"RIHS01_{PUBLISHED[typename]}"


def test_the_line_actions_parts_are_registered_with_their_fields():
    goal = TYPESTORE.fielddefs["control_msgs/action/FollowJointTrajectory_Goal"][1]
    assert [name for name, _ in goal][:3] == ["trajectory", "multi_dof_trajectory", "path_tolerance"]
    request = TYPESTORE.fielddefs["control_msgs/action/FollowJointTrajectory_SendGoal_Request"][1]
    assert [name for name, _ in request] == ["goal_id", "goal"]
    result = TYPESTORE.fielddefs["control_msgs/action/GripperCommand_Result"][1]
    assert [name for name, _ in result] == ["position", "effort", "stalled", "reached_goal"]


def test_messages_built_from_json_round_trip_through_cdr():
    values = {"status_list": [{"goal_info": {"goal_id": {"uuid": list(range(16))}, "stamp": {"sec": 3}}, "status": 4}]}
    message = from_json("action_msgs/msg/GoalStatusArray", values)
    back = TYPESTORE.deserialize_cdr(TYPESTORE.serialize_cdr(message, message.__msgtype__), message.__msgtype__)
    assert to_json(back) == {
        "status_list": [
            {"goal_info": {"goal_id": {"uuid": list(range(16))}, "stamp": {"sec": 3, "nanosec": 0}}, "status": 4}
        ]
    }
    feedback = from_json("control_msgs/action/FollowJointTrajectory_Feedback", {"joint_names": ["a"]})
    assert feedback.desired.positions.dtype == np.float64 and feedback.joint_names == ["a"], "left out: zeros"
