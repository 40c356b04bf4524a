"""The line's ROS 2 topics natively on its router, as rmw_zenoh lays them out: key expressions, type hashes and
attachments as rmw_zenoh documents them (a whole run heard by zenoh-ros2-sdk: `test_rosbridge.py`, whose line
serves both front ends)."""

import struct

from fleet.ros.rmw_zenoh import attachment, topic_key, type_hash


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
