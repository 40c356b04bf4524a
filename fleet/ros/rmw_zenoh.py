"""ROS 2 topics natively on the line's Zenoh router, laid out as rmw_zenoh (Jazzy/Kilted) lays them out, so a ROS 2
system with `RMW_IMPLEMENTATION=rmw_zenoh_cpp` connected to the router sees them with no bridge.

- Data: `<domain>/<name without its leading slash>/<pkg>::msg::dds_::<Name>_/<RIHS01 type hash>`, CDR bodies
  serialised by rosbags from its registered definitions (the hash is rosbags' RIHS01 of the same definition),
  each with the 33-byte attachment: sequence number (int64 LE), source timestamp (ns, int64 LE), GID length (1 byte,
  16) and the publisher's GID.
- Services: a queryable on `<domain>/<name>/<pkg>::srv::dds_::<Name>_/<hash of the service type>`; a request is a
  query whose payload is the request's CDR and whose attachment is the client's (sequence number, GID); the reply
  carries the response's CDR and the same sequence number and GID (rmw_zenoh's client matches on them).
- TRANSIENT_LOCAL publishers are Zenoh advanced publishers with a cache of their depth, which late subscribers
  query (`<key>/@adv/pub/...`), as rmw_zenoh's are.
- Discovery: liveliness tokens `@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<NN|MP|MS|SS>/<enclave>/<namespace>/
  <node>[/<name>/<type>/<hash>/<qos>]`, names with `/` mangled to `%`, QoS in rmw_zenoh's compact form.
"""

from __future__ import annotations

import itertools
import os
import struct
import threading
import time
from collections import deque

import zenoh
import zenoh.ext

from fleet.record.ros_types import TYPESTORE
from fleet.ros.ros_interfaces import register_interfaces

ADMIN = "@ros2_lv"
DEFAULT_QOS = "::,10:,:,:,,"  # reliable, volatile, keep last 10 (rmw_zenoh's default profile, elided fields)
LATCHED_QOS = ":1:,1:,:,:,,"  # transient local, keep last 1


def dds_type_name(typename: str) -> str:
    """`sensor_msgs/msg/JointState` -> `sensor_msgs::msg::dds_::JointState_`."""
    package, kind, name = typename.split("/")
    return f"{package}::{kind}::dds_::{name}_"


def type_hash(typename: str) -> str:
    """The RIHS01 hash of a registered type, message or service (`RIHS01_<64 hex>`)."""
    register_interfaces()
    return TYPESTORE.hash_rihs01(typename)


def topic_key(domain_id: int, name: str, typename: str) -> str:
    """A topic's data key expression."""
    return f"{domain_id}/{name.lstrip('/')}/{dds_type_name(typename)}/{type_hash(typename)}"


def mangle(name: str) -> str:
    return "%" if name in ("", "/") else name.replace("/", "%")


def attachment(seq: int, stamp_ns: int, gid: bytes) -> bytes:
    """rmw_zenoh's attachment of one sample (33 bytes for a 16-byte GID)."""
    return struct.pack("<qqB", seq, stamp_ns, len(gid)) + gid


def read_attachment(data: bytes) -> tuple[int, int, bytes]:
    """(sequence number, source timestamp ns, GID) of an attachment; ValueError for one that is not rmw_zenoh's."""
    if len(data) < 17 or len(data) != 17 + data[16]:
        raise ValueError(f"an rmw_zenoh attachment is 17 bytes and a GID, not {len(data)} bytes")
    seq, stamp_ns, _ = struct.unpack("<qqB", data[:17])
    return seq, stamp_ns, bytes(data[17:])


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
        self.endpoints: list[Ros2Publisher | Ros2Subscription | Ros2Service] = []

    def _declare(self, kind: str, name: str, typename: str, qos: str) -> None:
        """The liveliness token that makes one endpoint of this node known to the ROS graph."""
        entity = next(self._ids)
        token = (
            f"{self.prefix}/{entity}/{kind}/%/{mangle(self.namespace)}/{self.name}/"
            f"{mangle(name)}/{dds_type_name(typename)}/{type_hash(typename)}/{qos}"
        )
        self.tokens.append(self.session.liveliness().declare_token(token))

    def publisher(self, topic: str, typename: str, latched: bool = False) -> Ros2Publisher:
        """A publisher; `latched` is TRANSIENT_LOCAL, keep last 1: a late subscriber gets the last message."""
        self._declare("MP", topic, typename, LATCHED_QOS if latched else DEFAULT_QOS)
        pub = Ros2Publisher(self.session, topic_key(self.domain_id, topic, typename), typename, latched)
        self.endpoints.append(pub)
        return pub

    def subscription(self, topic: str, typename: str, wake: threading.Event) -> Ros2Subscription:
        """A subscription whose messages queue until the node's loop takes them (`wake` is set on each)."""
        self._declare("MS", topic, typename, DEFAULT_QOS)
        sub = Ros2Subscription(self.session, topic_key(self.domain_id, topic, typename), typename, wake)
        self.endpoints.append(sub)
        return sub

    def service(self, name: str, srv_type: str, wake: threading.Event) -> Ros2Service:
        """A service server whose requests queue until the node's loop answers them (`wake` is set on each)."""
        self._declare("SS", name, srv_type, DEFAULT_QOS)
        srv = Ros2Service(self.session, topic_key(self.domain_id, name, srv_type), srv_type, wake)
        self.endpoints.append(srv)
        return srv

    def close(self) -> None:
        for endpoint in self.endpoints:
            endpoint.close()
        for token in self.tokens:
            token.undeclare()


class Ros2Publisher:
    """Puts typestore messages on one topic's key as CDR with rmw_zenoh's attachment."""

    def __init__(self, session: zenoh.Session, key: str, typename: str, latched: bool = False) -> None:
        self.key, self.typename = key, typename
        self.gid = os.urandom(16)
        self.seq = 0
        cdr = zenoh.Encoding.APPLICATION_CDR
        if latched:
            cache = zenoh.ext.CacheConfig(max_samples=1)
            self._pub = zenoh.ext.declare_advanced_publisher(session, key, encoding=cdr, cache=cache)
        else:
            self._pub = session.declare_publisher(key, encoding=cdr)

    @property
    def heard(self) -> bool:
        """Whether any subscriber matches now (a latched topic: always, its cache serves late joiners)."""
        status = getattr(self._pub, "matching_status", None)
        return status is None or status.matching

    def put(self, message: object) -> None:
        self.seq += 1
        body = bytes(TYPESTORE.serialize_cdr(message, self.typename))
        self._pub.put(body, attachment=attachment(self.seq, time.time_ns(), self.gid))

    def close(self) -> None:
        self._pub.undeclare()


class Ros2Subscription:
    """Queues the typestore messages published on one topic (one that cannot be read is counted, not queued)."""

    def __init__(self, session: zenoh.Session, key: str, typename: str, wake: threading.Event) -> None:
        self.key, self.typename, self.wake = key, typename, wake
        self.items: deque = deque()
        self.unreadable = 0
        self._sub = session.declare_subscriber(key, self._on_sample)

    def _on_sample(self, sample: zenoh.Sample) -> None:
        self.items.append(sample.payload.to_bytes())  # decoded on the node's loop: callbacks only queue
        self.wake.set()

    def take(self) -> list[object]:
        out = []
        while self.items:
            try:
                out.append(TYPESTORE.deserialize_cdr(self.items.popleft(), self.typename))
            except Exception:  # rosbags raises its own and struct's errors on a body of another shape
                self.unreadable += 1
        return out

    def close(self) -> None:
        self._sub.undeclare()


class Ros2Request:
    """One service request: the message, and the query to answer (now or later, once)."""

    def __init__(self, query: zenoh.Query, message: object, seq: int, gid: bytes, response_type: str) -> None:
        self.query, self.message, self.seq, self.gid = query, message, seq, gid
        self.response_type = response_type

    def reply(self, response: object) -> None:
        body = bytes(TYPESTORE.serialize_cdr(response, self.response_type))
        self.query.reply(
            self.query.key_expr,
            body,
            encoding=zenoh.Encoding.APPLICATION_CDR,
            attachment=attachment(self.seq, time.time_ns(), self.gid),
        )
        self.query.drop()


class Ros2Service:
    """Queues the requests of one service; `take()` gives them decoded, each to be replied to once. A request
    that cannot be read (no attachment, another body) is answered with an error and counted."""

    def __init__(self, session: zenoh.Session, key: str, srv_type: str, wake: threading.Event) -> None:
        self.key, self.srv_type, self.wake = key, srv_type, wake
        self.request_type, self.response_type = f"{srv_type}_Request", f"{srv_type}_Response"
        self.items: deque = deque()
        self.unreadable = 0
        self._queryable = session.declare_queryable(key, self._on_query, complete=True)

    def _on_query(self, query: zenoh.Query) -> None:
        self.items.append(query)
        self.wake.set()

    def take(self) -> list[Ros2Request]:
        out = []
        while self.items:
            query = self.items.popleft()
            try:
                seq, _, gid = read_attachment(query.attachment.to_bytes() if query.attachment else b"")
                body = query.payload.to_bytes() if query.payload else b""
                message = TYPESTORE.deserialize_cdr(body, self.request_type)
            except Exception as exc:  # a request of another shape: rosbags and struct raise their own errors
                self.unreadable += 1
                query.reply_err(f"{self.srv_type}: unreadable request ({exc.__class__.__name__})".encode())
                query.drop()
                continue
            out.append(Ros2Request(query, message, seq, gid, self.response_type))
        return out

    def close(self) -> None:
        self._queryable.undeclare()
