"""The line's ROS 2 topics natively on its router, as rmw_zenoh lays them out: key expressions, type hashes and
attachments as rmw_zenoh documents them, and a whole secure run heard and discovered by zenoh-ros2-sdk (an
rmw_zenoh implementation clawfleet did not write, which derives the keys from the definitions itself)."""

import math
import struct

import pytest

from fleet.ros.rmw_zenoh import attachment, topic_key, type_hash
from tests.fleet.ros.rmw_zenoh_session import DOMAIN, TOPICS, rmw_zenoh_session
from tests.fleet.test_run import assert_nothing_left


def test_keys_hashes_and_attachments_are_rmw_zenohs():
    # rmw_zenoh's design document: `0/chatter/std_msgs::msg::dds_::String_/RIHS01_df668c74...`
    assert type_hash("std_msgs/msg/String") == (
        "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
    )
    assert topic_key(0, "/chatter", "std_msgs/msg/String").startswith("0/chatter/std_msgs::msg::dds_::String_/RIHS01_")
    assert topic_key(3, "/arm_0/joint_states", "sensor_msgs/msg/JointState").startswith(
        "3/arm_0/joint_states/sensor_msgs::msg::dds_::JointState_/"
    )
    gid = bytes(range(16))
    packed = attachment(42, 1_700_000_000_123_456_789, gid)
    assert len(packed) == 33 and struct.unpack("<qqB", packed[:17]) == (42, 1_700_000_000_123_456_789, 16)
    assert packed[17:] == gid


@pytest.mark.slow
def test_a_ros2_node_on_rmw_zenoh_hears_and_discovers_the_lines_topics(tmp_path):
    summary, heard = rmw_zenoh_session(tmp_path)
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
    assert summary["bus"] == "secure" and summary["bus_refused"] == {}, "every login stayed within its role"
    assert_nothing_left(summary, heard["endpoint"])
