"""Message definitions as rosapi (ROS 2) gives them to rosbridge clients: `message_details` (roslibjs'
`getMessageDetails`: a `rosapi_msgs/TypeDef` per type, its fields in IDL type names) and the full definition text
of `topics_and_raw_types` (what Foxglove's rosbridge connection decodes by), both from the registered types."""

from __future__ import annotations

from rosbags.typesys.store import Nodetype

from fleet.record.ros_types import TYPESTORE

IDL_NAMES = {"bool": "boolean", "byte": "octet", "char": "uint8", "float32": "float", "float64": "double"}
EXAMPLES = {"boolean": "False", "float": "0.0", "double": "0.0", "string": ""}


def full_name(typename: str) -> str:
    """`sensor_msgs/JointState` or `sensor_msgs/msg/JointState` -> the registered `sensor_msgs/msg/JointState`;
    KeyError for a type not registered."""
    parts = typename.split("/")
    name = f"{parts[0]}/msg/{parts[1]}" if len(parts) == 2 else typename
    if name not in TYPESTORE.fielddefs:
        raise KeyError(typename)
    return name


def short_name(typename: str) -> str:
    """`sensor_msgs/msg/JointState` -> `sensor_msgs/JointState`, as rosapi names types."""
    package, _, name = typename.split("/")
    return f"{package}/{name}"


def typedef(typename: str) -> dict:
    """One `rosapi_msgs/TypeDef`: field names, IDL types (nested types as `pkg/Name`), array lengths (-1 not an
    array, 0 a sequence, N fixed), example values, constants."""
    consts, fields = TYPESTORE.fielddefs[typename]
    out = {"type": short_name(typename), "fieldnames": [], "fieldtypes": [], "fieldarraylen": [], "examples": []}
    for name, (node, detail) in fields:
        length = -1
        if node in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            length = detail[1] if node == Nodetype.ARRAY else 0
            node, detail = detail[0]
        kind = short_name(detail) if node == Nodetype.NAME else IDL_NAMES.get(detail[0], detail[0])
        out["fieldnames"].append(name)
        out["fieldtypes"].append(kind)
        out["fieldarraylen"].append(length)
        out["examples"].append("[]" if length >= 0 else "{}" if node == Nodetype.NAME else EXAMPLES.get(kind, "0"))
    out["constnames"] = [c[0] for c in consts]
    out["constvalues"] = [str(c[2]) for c in consts]
    return out


def message_details(typename: str) -> list[dict]:
    """The type's `TypeDef` and those of every type inside it, each once (rosapi's `message_details`)."""
    order, todo = [], [full_name(typename)]
    while todo:
        name = todo.pop(0)
        if name in order:
            continue
        order.append(name)
        for _, (node, detail) in TYPESTORE.fielddefs[name][1]:
            if node in (Nodetype.ARRAY, Nodetype.SEQUENCE):
                node, detail = detail[0]
            if node == Nodetype.NAME:
                todo.append(detail)
    return [typedef(name) for name in order]


def full_text(typename: str) -> str:
    """The definition with every type it uses (`MSG: pkg/Name` sections), as `topics_and_raw_types` gives it."""
    return TYPESTORE.generate_msgdef(full_name(typename), ros_version=2)[0]
