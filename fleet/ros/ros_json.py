"""ROS messages as rosbridge's JSON carries them: a typestore message (rosbags) as nested dicts of its fields,
arrays as lists, but byte sequences (`uint8[]`, as an image's data) as base64 strings, as rosbridge_suite sends them;
NaN and infinities as null (JSON has none of them; browsers' parsers refuse them)."""

from __future__ import annotations

import base64
import dataclasses
import math

import numpy as np
from rosbags.typesys.store import Nodetype

from fleet.record.ros_types import TYPESTORE

_FIELDS: dict[type, tuple[str, ...] | None] = {}  # a message type's field names (None: not a message)
_PLAIN = (str, int, bool, type(None))
BYTE_TYPES = ("uint8", "byte", "char")


def _fields(kind: type) -> tuple[str, ...] | None:
    """A message type's ROS fields (rosbags' classes also carry the constants and `__msgtype__` as fields)."""
    if kind not in _FIELDS:
        typename = getattr(kind, "__msgtype__", None)
        if isinstance(typename, str) and typename in TYPESTORE.fielddefs:
            _FIELDS[kind] = tuple(name for name, _ in TYPESTORE.fielddefs[typename][1])
        else:
            _FIELDS[kind] = tuple(f.name for f in dataclasses.fields(kind)) if dataclasses.is_dataclass(kind) else None
    return _FIELDS[kind]


_BYTES: dict[type, frozenset[str]] = {}


def _byte_sequences(kind: type) -> frozenset[str]:
    """A message type's `uint8[]` (and `byte[]`, `char[]`) sequence fields, which rosbridge sends as base64 (an
    image's data); fixed byte arrays (a goal's uuid) stay lists."""
    if kind not in _BYTES:
        typename = getattr(kind, "__msgtype__", None)
        fields = (
            TYPESTORE.fielddefs[typename][1] if isinstance(typename, str) and typename in TYPESTORE.fielddefs else []
        )
        _BYTES[kind] = frozenset(
            name
            for name, (node, detail) in fields
            if node == Nodetype.SEQUENCE and detail[0][0] == Nodetype.BASE and detail[0][1][0] in BYTE_TYPES
        )
    return _BYTES[kind]


def to_json(message: object, raw_bytes: bool = False) -> object:
    """A rosbags typestore message (or any value inside one) as JSON-able Python values; `raw_bytes`: byte sequences
    as bytes, as rosbridge's CBOR carries them, not base64."""
    kind = type(message)
    if kind in _PLAIN:
        return message
    if kind is float:
        return message if math.isfinite(message) else None
    names = _fields(kind)
    if names is not None:
        packed = _byte_sequences(kind)
        return {
            name: _packed(getattr(message, name), raw_bytes)
            if name in packed
            else to_json(getattr(message, name), raw_bytes)
            for name in names
        }
    if kind is np.ndarray:
        values = message.tolist()
        if message.dtype.kind == "f" and not np.isfinite(message).all():
            return [v if math.isfinite(v) else None for v in values]
        return values if message.dtype.kind in "fiub" else [to_json(v, raw_bytes) for v in values]
    if isinstance(message, (list, tuple)):
        return [to_json(v, raw_bytes) for v in message]
    if isinstance(message, dict):
        return {k: to_json(v, raw_bytes) for k, v in message.items()}
    if isinstance(message, np.generic):
        return to_json(message.item())
    return message


def _packed(values: np.ndarray, raw_bytes: bool) -> str | bytes:
    return values.tobytes() if raw_bytes else base64.b64encode(values.tobytes()).decode("ascii")


def time_json(sim_time_s: float) -> dict:
    """`builtin_interfaces/Time` (or `Duration`) of a time in seconds."""
    ns = max(0, round(sim_time_s * 1e9))
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def seconds(value: object, field: str) -> float:
    """Seconds of a `builtin_interfaces/Duration` or `Time` in JSON ({sec, nanosec}); ValueError names `field`."""
    if not isinstance(value, dict):
        raise ValueError(f"{field} must be {{sec, nanosec}}, not {type(value).__name__}")
    sec, nanosec = value.get("sec", 0), value.get("nanosec", value.get("nsec", 0))
    if not all(isinstance(v, int) and not isinstance(v, bool) for v in (sec, nanosec)):
        raise ValueError(f"{field}: sec and nanosec must be integers")
    return sec + nanosec * 1e-9


_DTYPES = {"bool": np.bool_, "byte": np.uint8, "char": np.uint8, "float32": np.float32, "float64": np.float64,
           "int8": np.int8, "uint8": np.uint8, "int16": np.int16, "uint16": np.uint16, "int32": np.int32,
           "uint32": np.uint32, "int64": np.int64, "uint64": np.uint64}  # fmt: skip


def from_json(typename: str, values: dict) -> object:
    """A typestore message from JSON-like values (the inverse of `to_json`); a field left out takes its zero, as
    rosbridge fills a message. For messages this process builds itself (results, feedback, status)."""
    _, fields = TYPESTORE.fielddefs[typename]
    kwargs = {name: _field_value(desc, values.get(name)) for name, desc in fields}
    return TYPESTORE.types[typename](**kwargs)


def _field_value(desc: tuple, value: object) -> object:
    node, detail = desc
    if node == Nodetype.NAME:
        return from_json(detail, value or {})
    if node == Nodetype.BASE:
        return _zero(detail[0]) if value is None else value
    (item_node, item), count = detail
    if isinstance(value, str) and item_node == Nodetype.BASE and item[0] in BYTE_TYPES:
        value = base64.b64decode(value, validate=True)  # rosbridge's byte arrays
    items = list(value or ())
    if node == Nodetype.ARRAY:
        items = (items + [None] * count)[:count]
    if item_node == Nodetype.BASE and item[0] in _DTYPES:
        return np.array([0 if v is None else v for v in items], dtype=_DTYPES[item[0]])
    return [_field_value((item_node, item), v) for v in items]


def _zero(kind: str) -> object:
    if kind in ("string", "wstring"):
        return ""
    return False if kind == "bool" else 0.0 if kind.startswith("float") else 0
