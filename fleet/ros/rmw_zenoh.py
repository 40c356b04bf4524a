"""ROS 2 topics natively on the line's Zenoh router, laid out as rmw_zenoh (Jazzy/Kilted) lays them out, so a ROS 2
system with `RMW_IMPLEMENTATION=rmw_zenoh_cpp` connected to the router sees them with no bridge.

- Data: `<domain>/<name without its leading slash>/<pkg>::msg::dds_::<Name>_/<RIHS01 type hash>`, CDR bodies
  serialised by rosbags from its registered definitions (the hash is rosbags' RIHS01 of the same definition),
  each with the 33-byte attachment: sequence number (int64 LE), source timestamp (ns, int64 LE), GID length (1 byte,
  16) and the publisher's GID.
- Discovery: liveliness tokens `@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<NN|MP>/<enclave>/<namespace>/<node>
  [/<name>/<type>/<hash>/<qos>]`, names with `/` mangled to `%`, QoS in rmw_zenoh's compact form.
"""

from __future__ import annotations

import itertools
import os
import struct
import time

import zenoh

from fleet.record.ros_types import TYPESTORE

ADMIN = "@ros2_lv"
DEFAULT_QOS = "::,10:,:,:,,"  # reliable, volatile, keep last 10 (rmw_zenoh's default profile, elided fields)
LATCHED_QOS = ":1:,1:,:,:,,"  # transient local, keep last 1


def dds_type_name(typename: str) -> str:
    """`sensor_msgs/msg/JointState` -> `sensor_msgs::msg::dds_::JointState_`."""
    package, kind, name = typename.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def type_hash(typename: str) -> str:
    """The RIHS01 hash of a registered type (`RIHS01_<64 hex>`)."""
    return TYPESTORE.hash_rihs01(typename)


def topic_key(domain_id: int, name: str, typename: str) -> str:
    """A topic's data key expression."""
    return f"{domain_id}/{name.lstrip('/')}/{dds_type_name(typename)}/{type_hash(typename)}"


def mangle(name: str) -> str:
    return "%" if name in ("", "/") else name.replace("/", "%")


def attachment(seq: int, stamp_ns: int, gid: bytes) -> bytes:
    """rmw_zenoh's attachment of one sample (33 bytes for a 16-byte GID)."""
    return struct.pack("<qqB", seq, stamp_ns, len(gid)) + gid


class Ros2Node:
    """One ROS 2 node on a Zenoh session: its liveliness token, and publishers with theirs."""

    def __init__(self, session: zenoh.Session, domain_id: int, name: str, namespace: str = "/") -> None:
        self.session, self.domain_id, self.name, self.namespace = session, domain_id, name, namespace
        self.zid = str(session.info.zid())
        self._ids = itertools.count(1)
        self.node_id = next(self._ids)
        self.prefix = f"{ADMIN}/{domain_id}/{self.zid}/{self.node_id}"
        self.tokens = [
            session.liveliness().declare_token(f"{self.prefix}/{self.node_id}/NN/%/{mangle(namespace)}/{name}")
        ]
        self.publishers: list[Ros2Publisher] = []

    def publisher(self, topic: str, typename: str, latched: bool = False) -> Ros2Publisher:
        entity = next(self._ids)
        qos = LATCHED_QOS if latched else DEFAULT_QOS
        token = (
            f"{self.prefix}/{entity}/MP/%/{mangle(self.namespace)}/{self.name}/"
            f"{mangle(topic)}/{dds_type_name(typename)}/{type_hash(typename)}/{qos}"
        )
        self.tokens.append(self.session.liveliness().declare_token(token))
        pub = Ros2Publisher(self.session, topic_key(self.domain_id, topic, typename), typename)
        self.publishers.append(pub)
        return pub

    def close(self) -> None:
        for pub in self.publishers:
            pub.close()
        for token in self.tokens:
            token.undeclare()


class Ros2Publisher:
    """Puts typestore messages on one topic's key as CDR with rmw_zenoh's attachment."""

    def __init__(self, session: zenoh.Session, key: str, typename: str) -> None:
        self.key, self.typename = key, typename
        self.gid = os.urandom(16)
        self.seq = 0
        self._pub = session.declare_publisher(key, encoding=zenoh.Encoding.APPLICATION_CDR)

    def put(self, message: object) -> None:
        self.seq += 1
        body = bytes(TYPESTORE.serialize_cdr(message, self.typename))
        self._pub.put(body, attachment=attachment(self.seq, time.time_ns(), self.gid))

    def close(self) -> None:
        self._pub.undeclare()
