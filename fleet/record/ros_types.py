"""ROS 2 message types for recordings: the standard ones from rosbags' typestore (ROS 2 Jazzy definitions),
and `clawfleet_msgs/msg/<Name>` types generated from the bus messages themselves, so the two never drift.

A generated type has one field per bus field (the protocol `version` left out) in ROS's own primitive types;
an optional value is written as its sentinel: -1 for a missing integer (e.g. `task_id`), NaN for a missing
float (e.g. a goal's `start_time_s`: on receipt). Messages are serialised as CDR by rosbags, never by hand.
"""

from __future__ import annotations

import math
from functools import cache

import msgspec.inspect as mi
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from fleet.bus.messages import MESSAGE_TYPES, Message

PACKAGE = "clawfleet_msgs"
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
NONE_INT = -1
_BUS_TYPES_BY_NAME = {t.__name__: t for t in MESSAGE_TYPES}
_PRIMITIVES = {mi.IntType: "int64", mi.FloatType: "float64", mi.StrType: "string", mi.BoolType: "bool"}


def ros_type(name: str):
    """The message class of a ROS type name (`sensor_msgs/msg/JointState`); a generated one after `bus_type`."""
    return TYPESTORE.types[name]


def msgdef(typename: str) -> str:
    """The type's definition with its dependencies, as rosbag2 writes it into an MCAP schema (`ros2msg`). A
    generated type is registered here if this process has not built one of its messages yet (they may have been
    built in a forked child)."""
    if typename.startswith(f"{PACKAGE}/msg/") and typename not in TYPESTORE.types:
        bus_type(_BUS_TYPES_BY_NAME[typename.rsplit("/", 1)[1]])
    return TYPESTORE.generate_msgdef(typename, ros_version=2)[0]


def serialize(message: object) -> bytes:
    """CDR bytes of a typestore message."""
    return bytes(TYPESTORE.serialize_cdr(message, message.__msgtype__))


def deserialize(data: bytes, typename: str) -> object:
    return TYPESTORE.deserialize_cdr(data, typename)


def time_msg(sim_time_s: float):
    """`builtin_interfaces/Time` of a sim time (sim time is the recording's clock)."""
    ns = sim_ns(sim_time_s)
    return ros_type("builtin_interfaces/msg/Time")(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def sim_ns(sim_time_s: float) -> int:
    """Nanoseconds of sim time, as MCAP log times are kept (never negative)."""
    return max(0, round(sim_time_s * 1e9))


def _field_type(info: mi.Type) -> tuple[str, object]:
    """The ROS field type of a bus field and its value for None."""
    if isinstance(info, mi.UnionType):
        (inner,) = [t for t in info.types if not isinstance(t, mi.NoneType)]
        ros, _ = _field_type(inner)
        return ros, NONE_INT if ros == "int64" else math.nan
    if isinstance(info, mi.VarTupleType):
        ros, _ = _field_type(info.item_type)
        return f"{ros}[]", None
    try:
        return _PRIMITIVES[type(info)], None
    except KeyError:
        raise TypeError(f"no ROS field type for {info!r}") from None


@cache
def bus_type(message_type: type[Message]) -> str:
    """Register `clawfleet_msgs/msg/<Name>` for a flat bus message type; its ROS type name."""
    name = f"{PACKAGE}/msg/{message_type.__name__}"
    fields = [f for f in mi.type_info(message_type).fields if f.name != "version"]
    lines = [f"{_field_type(f.type)[0]} {f.name}" for f in fields]
    TYPESTORE.register(get_types_from_msg("\n".join(lines), name))
    return name


@cache
def _fields(message_type: type[Message]) -> tuple[tuple[str, mi.Type, object], ...]:
    """(name, type, value for None) of every field but `version`."""
    return tuple(
        (f.name, f.type, _field_type(f.type)[1]) for f in mi.type_info(message_type).fields if f.name != "version"
    )


def to_ros(message: Message) -> object:
    """The generated ROS message of a bus message (optional values as their sentinels)."""
    values = {}
    for name, info, none in _fields(type(message)):
        value = getattr(message, name)
        if value is None:
            value = none
        elif isinstance(value, tuple):
            value = _array(value, info.item_type)
        values[name] = value
    return ros_type(bus_type(type(message)))(**values)


def _array(values: tuple, item: mi.Type):
    """A ROS array field: numpy for numbers (as rosbags wants), a list for strings."""
    import numpy as np

    if isinstance(item, mi.StrType):
        return list(values)
    return np.asarray(values, dtype={mi.IntType: np.int64, mi.FloatType: np.float64, mi.BoolType: np.bool_}[type(item)])
