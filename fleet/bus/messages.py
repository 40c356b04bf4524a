"""Every message on the bus, typed with a protocol version, encoded as compact MessagePack.

Messages are msgspec Structs: frozen, typed dataclass-like records that encode
as MessagePack arrays (no field names on the wire) and decode with type checks.

Joint vectors are tuples of floats in the arm spec's joint order; poses are
world frame, metres, quaternions wxyz (docs/conventions.md). `docs/protocol.md`
lists which key carries which message.
"""

from __future__ import annotations

import msgspec

PROTOCOL_VERSION = 1
Floats = tuple[float, ...]


class Message(msgspec.Struct, frozen=True, array_like=True):
    """Base of all bus messages."""


class ArmState(Message, frozen=True, array_like=True):
    """Sim -> controller, every control tick: one arm's joints, gripper and tool pose."""

    arm: str
    tick: int
    sim_time_s: float
    q: Floats
    dq: Floats
    gripper_q: Floats
    tool_position: Floats
    tool_quaternion_wxyz: Floats
    held: bool = False
    version: int = PROTOCOL_VERSION


class ArmCommandMsg(Message, frozen=True, array_like=True):
    """Controller -> sim: joint targets answering the state of `tick`."""

    arm: str
    tick: int
    q: Floats
    dq: Floats
    gripper_opening: float
    version: int = PROTOCOL_VERSION


class ArmStatus(Message, frozen=True, array_like=True):
    """Controller -> everyone, a heartbeat with what the arm is doing."""

    arm: str
    seq: int
    sim_time_s: float
    skill: str
    task_id: int | None
    progress: float
    version: int = PROTOCOL_VERSION


class PartsState(Message, frozen=True, array_like=True):
    """Sim -> everyone, every control tick: each active part's pose and velocity (flattened triples/quads)."""

    tick: int
    sim_time_s: float
    part_ids: tuple[int, ...]
    feeders: tuple[str, ...]
    type_indices: tuple[int, ...]
    positions: Floats
    quaternions_wxyz: Floats
    velocities: Floats
    sizes_m: Floats
    version: int = PROTOCOL_VERSION


class Assignment(Message, frozen=True, array_like=True):
    """Coordinator -> controller: pick `part_id` from a surface and place it; `task_id` None cancels."""

    arm: str
    task_id: int | None
    part_id: int
    surface_z_m: float
    place_xyz: Floats
    surface_velocity: Floats
    version: int = PROTOCOL_VERSION


class LineEvent(Message, frozen=True, array_like=True):
    """Sim or controller -> coordinator: a part arrived, was placed, or was lost."""

    kind: str
    part_id: int
    tick: int
    detail: str = ""
    version: int = PROTOCOL_VERSION


class EStop(Message, frozen=True, array_like=True):
    """Anyone -> sim: engage (hold every arm within one tick) or release the emergency stop."""

    engaged: bool
    source: str
    version: int = PROTOCOL_VERSION


MESSAGE_TYPES = (ArmState, ArmCommandMsg, ArmStatus, PartsState, Assignment, LineEvent, EStop)
