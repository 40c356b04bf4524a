"""ROS messages as rosbridge's JSON carries them: a typestore message (rosbags) as nested dicts of its fields,
arrays as lists, NaN and infinities as null (JSON has none of them; browsers' parsers refuse them)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np


def to_json(message: object) -> object:
    """A rosbags typestore message (or any value inside one) as JSON-able Python values."""
    if dataclasses.is_dataclass(message):
        return {f.name: to_json(getattr(message, f.name)) for f in dataclasses.fields(message)}
    if isinstance(message, np.ndarray):
        return [to_json(v) for v in message.tolist()]
    if isinstance(message, (list, tuple)):
        return [to_json(v) for v in message]
    if isinstance(message, dict):
        return {k: to_json(v) for k, v in message.items()}
    if isinstance(message, float):
        return message if math.isfinite(message) else None
    if isinstance(message, np.generic):
        return to_json(message.item())
    return message


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
