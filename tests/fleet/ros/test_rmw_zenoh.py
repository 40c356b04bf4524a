"""The line's ROS 2 topics natively on its router, as rmw_zenoh lays them out: key expressions, type hashes and
attachments as rmw_zenoh documents them (a whole run heard by zenoh-ros2-sdk: `test_rosbridge.py`, whose line
serves both front ends)."""

import struct
import threading

import pytest

from fleet.bus.session import BusEndpoints, free_loopback_port, loopback_endpoint, open_session
from fleet.record.ros_types import TYPESTORE
from fleet.ros.rmw_zenoh import Ros2Node, attachment, read_attachment, topic_key, type_hash
from fleet.ros.ros_interfaces import register_interfaces
from fleet.ros.ros_json import from_json


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


def test_a_service_answers_requests_and_refuses_unreadable_ones_with_an_error():
    """A real service on a loopback session, asked as rmw_zenoh's clients ask: a query with the request's CDR and
    the client's attachment; the reply carries the response and the client's sequence number and GID."""
    register_interfaces()
    endpoint = loopback_endpoint(free_loopback_port())
    with open_session(BusEndpoints(listen=(endpoint,))) as session:
        node = Ros2Node(session, 5, "probe")
        wake = threading.Event()
        service = node.service("/estop", "std_srvs/srv/SetBool", wake)
        request = from_json("std_srvs/srv/SetBool_Request", {"data": True})
        body = bytes(TYPESTORE.serialize_cdr(request, "std_srvs/srv/SetBool_Request"))
        gid = bytes(range(16))
        replies = []

        def answer() -> None:
            assert wake.wait(5)
            for r in service.take():
                r.reply(from_json(service.response_type, {"success": r.message.data, "message": "ok"}))

        for payload, attached in ((body, attachment(7, 1, gid)), (b"\x00", attachment(8, 1, gid)), (body, None)):
            wake.clear()
            answering = threading.Thread(target=answer)
            answering.start()
            replies.append(list(session.get(service.key, payload=payload, attachment=attached, timeout=5)))
            answering.join()
        node.close()
    ok = replies[0][0].ok
    response = TYPESTORE.deserialize_cdr(ok.payload.to_bytes(), "std_srvs/srv/SetBool_Response")
    assert response.success and read_attachment(ok.attachment.to_bytes())[::2] == (7, gid)
    assert [r[0].err is not None for r in replies[1:]] == [True, True], "unreadable body, no attachment: errors"
    assert service.unreadable == 2
    with pytest.raises(ValueError):
        read_attachment(b"\x01" * 20)
