"""The ROS 2 front ends of one running (secure) line, checked with clients clawfleet did not write: rosbridge with
roslibpy (the line's topics, actions and services as ROS tools see them; FollowJointTrajectory with
ros2_controllers' semantics: success within tolerance, refusals with their codes, preemption and cancel ending
CANCELED, the e-stop aborting; bad requests answered with a status error and the line untouched), and the native
rmw_zenoh topics with zenoh-ros2-sdk (which derives the keys from the definitions itself)."""

import math
import re
import socket

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from fleet.ros.rmw_zenoh import topic_key
from tests.fleet.ros.rmw_zenoh_session import DOMAIN, TOPICS, Ros2Listener
from tests.fleet.ros.rosbridge_session import rosbridge_session
from tests.fleet.test_run import assert_nothing_left

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out

SUCCEEDED, CANCELED, ABORTED, UNKNOWN = 4, 5, 6, 0


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    summary, seen = rosbridge_session(Ros2Listener(tmp_path_factory.mktemp("ros_definitions")))
    assert "error" not in seen, seen["error"]
    return summary, seen


def test_a_ros_client_sees_the_lines_topics_actions_and_frames(session):
    _, seen = session
    for topic in ("/joint_states", "/tf", "/tf_static", "/clock", "/arm_0/joint_states", "/arm_1/joint_states"):
        assert topic in seen["topics"]
    assert set(seen["actions"]) >= {"/arm_0/follow_joint_trajectory", "/arm_1/follow_joint_trajectory"}
    assert "arm_0/elbow" in seen["everyone_names"] and "arm_1/elbow" in seen["everyone_names"]
    assert set(seen["after_reach"]) == {"header", "name", "position", "velocity", "effort"}, "a message's own fields"
    details = {t["type"]: t for t in seen["details"]["typedefs"]}
    assert details["sensor_msgs/JointState"]["fieldtypes"][:3] == ["std_msgs/Header", "string", "double"]
    assert "builtin_interfaces/Time" in details, "and every type inside it"
    raw = dict(zip(seen["raw_types"]["topics"], seen["raw_types"]["typedefs_full_text"]))
    assert raw["/tf"].startswith("geometry_msgs/TransformStamped[] transforms"), "definitions Foxglove decodes by"
    frames = {t["child_frame_id"] for t in seen["tf_static"][0]["transforms"]}
    assert any(f.startswith("arm_0/") for f in frames), "the arms' roots on /tf_static, latched"


def test_foxglove_s_rosbridge_asks_are_answered_node_details_cbor_and_cdr_bytes_rosbags_decodes(session):
    _, seen = session
    details = seen["node_details"]
    assert "/joint_states" in details["publishing"] and "/arm_0/joint_trajectory" in details["subscribing"]
    assert "/rosapi/node_details" in details["services"]
    line = ["/clawfleet/sim_server", "/clawfleet/coordinator", "/clawfleet/arm_0", "/clawfleet/arm_1"]
    assert seen["nodes"] == ["/clawfleet_rosbridge", *line], "the node serving ROS, then the line's own processes"
    store = get_typestore(Stores.ROS2_HUMBLE)  # rosbags' own definitions, not the line's
    raws = seen["cbor_raw"]
    assert len(raws) == 3 and all(r["op"] == "publish" and r["topic"] == "/joint_states" for r in raws), raws[:1]
    states = [store.deserialize_cdr(r["msg"]["bytes"], "sensor_msgs/msg/JointState") for r in raws]
    assert "arm_0/elbow" in states[-1].name and len(states[-1].position) == len(states[-1].name)
    stamps = [r["msg"]["secs"] + r["msg"]["nsecs"] * 1e-9 for r in raws]
    assert stamps == sorted(stamps) and stamps[-1] > 0, "stamped with the line's clock"
    (tf_static,) = seen["cbor"]
    frames = {t["child_frame_id"] for t in tf_static["msg"]["transforms"]}
    assert any(f.startswith("arm_0/") for f in frames), "the latched message, as CBOR"
    (refused,) = seen["png"]
    assert refused["level"] == "error" and "compression 'png' is not served" in refused["msg"], refused


def test_rosout_says_at_its_levels_what_the_user_did_to_the_arms_and_what_the_plant_refused(session):
    _, seen = session
    said = [(m["level"], m["name"], m["msg"]) for m in seen["rosout"]]
    assert (20, "clawfleet.arm_0", "arm_0: taken by an outside driver") in said, said
    assert (30, "clawfleet.arm_1", "arm_1: held by the line (e-stop or watchdog)") in said, "the e-stop holds all"
    assert (20, "clawfleet.arm_1", "arm_1: no longer held") in said, "and lets go"
    refused = [m for level, name, m in said if level == 30 and "rejected: safety" in m and name == "clawfleet.arm_0"]
    assert any("of arm_1" in m for m in refused), "the goal into arm_1's space, with the plant's reason"
    assert all(m["stamp"]["sec"] >= 0 for m in seen["rosout"]) and "/rosout" in seen["topics"]


def test_twenty_clients_subscribed_at_once_each_get_the_joint_states(session):
    _, seen = session
    assert len(seen["crowd"]) == 20 and min(seen["crowd"]) >= 5, seen["crowd"]


def test_a_trajectory_goal_succeeds_and_the_arm_stands_where_it_was_sent(session):
    _, seen = session
    reach = seen["reach"]
    assert reach["accepted"] and reach["status"] == SUCCEEDED, reach
    assert reach["values"]["error_code"] == 0 and reach["feedback"], "feedback while it ran"
    fb = reach["feedback"][-1]
    assert len(fb["actual"]["positions"]) == 6 and fb["joint_names"][0] == "shoulder_pan"
    reached = np.array(seen["after_reach"]["position"][:6])
    assert np.allclose(reached, seen["target"], atol=0.03), (reached, seen["target"])


def test_goals_that_cannot_run_are_refused_with_their_codes(session):
    _, seen = session
    assert not seen["unknown_joints"]["accepted"] and seen["unknown_joints"]["values"]["error_code"] == -2
    into = seen["into_neighbour"]
    assert not into["accepted"] and into["values"]["error_code"] == -1, into
    assert into["values"]["error_string"].startswith("safety:"), "the plant's safety layer refused it"
    assert not seen["unreadable"]["accepted"] and "positions" in seen["unreadable"]["values"]["error_string"]


def test_preemption_and_cancel_end_canceled_and_the_estop_aborts(session):
    _, seen = session
    assert seen["preempted"]["status"] == CANCELED, seen["preempted"]
    assert seen["preempting"]["status"] == SUCCEEDED
    assert seen["cancelled"]["status"] == CANCELED, seen["cancelled"]
    assert seen["estopped"]["status"] == ABORTED, seen["estopped"]
    assert "emergency stop" in seen["estopped"]["values"]["error_string"]
    assert seen["estop_answer"]["success"] is True
    assert seen["after_all"]["status"] == SUCCEEDED, "released, the arm takes goals again"


def test_the_claw_takes_gripper_commands_and_a_published_trajectory_moves_an_arm(session):
    _, seen = session
    closed, opened = seen["claw_closed"], seen["claw_opened"]
    assert closed["accepted"] and closed["status"] == SUCCEEDED and closed["values"]["reached_goal"], closed
    assert opened["status"] == SUCCEEDED and opened["values"]["position"] > closed["values"]["position"] + 0.02
    assert np.allclose(seen["arm_1_after"], seen["arm_1_target"], atol=0.03), "fire and forget, followed"


def test_bad_requests_get_a_status_error_and_leave_the_line_alone(session):
    summary, seen = session
    answers = seen["raw"]
    assert all(a["op"] == "status" and a["level"] == "error" for a in answers), answers
    assert "not JSON" in answers[0]["msg"] and "unknown op 'fly'" in answers[1]["msg"]
    assert answers[2]["id"] == "s1" and "/nope" in answers[2]["msg"]
    assert "no action '/arm_9/follow_joint_trajectory'" in answers[3]["msg"]
    assert "SetBool" in answers[4]["msg"]
    assert summary["status"] == "interrupted", summary["error"]  # stopped once the ROS user was done
    assert summary["inter_arm_contacts"] == 0 and summary["arms_lost"] == []


def test_the_run_ends_cleanly_with_the_bridge(session):
    summary, seen = session
    assert_nothing_left(summary, seen["endpoint"])
    with pytest.raises(ConnectionRefusedError):  # nothing listens on the WebSocket port any more
        socket.create_connection(("127.0.0.1", seen["ws_port"]), timeout=2).close()


def test_a_ros2_node_on_rmw_zenoh_hears_and_discovers_the_lines_topics(session):
    summary, seen = session
    heard = seen["ros2"]
    assert "error" not in heard, heard["error"]
    for topic, typename in TOPICS.items():
        assert heard[topic], f"nothing heard on {topic}"
        assert heard["keys"][topic] == topic_key(DOMAIN, topic, typename), "the SDK derived the same key"
    names = {n.split("/")[0] for m in heard["/joint_states"] for n in m.name}
    assert names <= {"arm_0", "arm_1"} and names, "every arm's joints, named by arm"
    assert all(math.isfinite(p) for m in heard["/joint_states"] for p in m.position)
    clocks = [c.clock.sec + c.clock.nanosec * 1e-9 for c in heard["/clock"]]
    assert clocks == sorted(clocks) and clocks[-1] > 0
    assert any(t.child_frame_id.startswith("arm_") for t in heard["/tf"][-1].transforms)
    graph = heard["graph"]
    assert graph["/arm_1/joint_states"] == ["sensor_msgs/msg/JointState"] and "/tf_static" in graph
    assert summary["bus"] == "secure"


def test_a_ros2_node_on_rmw_zenoh_calls_the_estop_and_drives_an_arm_through_its_action(session):
    _, seen = session
    heard = seen["ros2"]
    assert "error" not in heard, heard["error"]
    assert [(r.success, r.message) for r in heard["estop"]] == [
        (True, "emergency stop engaged"),
        (True, "emergency stop released"),
    ]
    assert heard["tf_static"], "a late subscriber got the latched /tf_static from the publisher's cache"
    assert heard["sent"].accepted and heard["result"].status == SUCCEEDED, heard["result"]
    assert heard["result"].result.error_code == 0
    first = [m.feedback for m in heard["feedback"] if bytes(m.goal_id.uuid) == bytes([1] * 16)]
    final = first[-1]
    assert list(final.joint_names)[0] == "shoulder_pan"
    assert np.allclose(final.actual.positions, heard["target"], atol=0.05), "feedback follows the arm to its target"
    statuses = {(bytes(s.goal_info.goal_id.uuid)[0], s.status) for m in heard["status"] for s in m.status_list}
    assert {(1, 2), (1, SUCCEEDED)} <= statuses, "executing, then succeeded, on the status topic"
    assert not heard["unknown_joints"].accepted, "a goal the line refuses is not accepted"
    assert heard["slow"].accepted and heard["cancel"].return_code == 0
    assert [bytes(g.goal_id.uuid)[0] for g in heard["cancel"].goals_canceling] == [3]
    assert heard["cancelled"].status == CANCELED


def test_a_pyzeros_node_hears_the_joints_and_the_clock_and_calls_the_estop(session):
    """pyzeros derives the type hashes and CDR from its own message definitions (ros2_pyterfaces)."""
    _, seen = session
    heard = seen["ros2"]["pyzeros"]
    assert {n.split("/")[0] for n in heard["/joint_states"].name} == {"arm_0", "arm_1"}
    assert heard["/clock"].clock.sec >= 0 and heard["estop"].success
    assert heard["estop"].message == "emergency stop released"


def test_the_ros_client_login_drives_only_the_arms_it_is_given(session):
    summary, seen = session
    assert seen["ros2"]["arm_0"] is None, "arm_0's goal got no answer: the router refused it"
    refused = list(summary["bus_refused"])  # "<login>: <what, in Zenoh's words> on <key>"
    # the goal, and the cancel a client may send when its goal gets no answer (the audit counts the whole run)
    arm_0_goals = re.compile(r"arm_0[/%]follow_joint_trajectory[/%]_action[/%](send_goal|cancel_goal|get_result)")
    assert refused and all(k.startswith("ros_client: ") and arm_0_goals.search(k) for k in refused), (
        "the router refused arm_0's action calls (their queries, or the client's declarations) and nothing of any"
        " other login",
        refused,
    )
