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
    """Sim -> controller and coordinator, every control tick: one arm's joints, gripper and tool pose.

    `task_id`, `skill` and `progress` echo the command applied last, so the coordinator
    learns what each arm does in step with the sim clock. `assign_seq` is the newest
    assignment the coordinator had published to this arm when this tick began: a controller
    acts on an assignment at the first state announcing it (lockstep with a coordinator; -1
    otherwise: act on arrival).
    `held` is true while the arm is held (e-stop, watchdog, lost controller); `lost` once
    its controller went silent in lockstep.
    """

    arm: str
    tick: int
    sim_time_s: float
    q: Floats
    dq: Floats
    gripper_q: Floats
    tool_position: Floats
    tool_quaternion_wxyz: Floats
    held: bool = False
    lost: bool = False
    task_id: int | None = None
    skill: str = "idle"
    progress: float = 0.0
    assign_seq: int = 0
    failure: str = ""
    request_seq: int = 0  # echo of the command's motion request (see ArmCommandMsg)
    request_q_to: Floats = ()
    request_duration_s: float = 0.0
    version: int = PROTOCOL_VERSION


class ArmCommandMsg(Message, frozen=True, array_like=True):
    """Controller -> sim: joint targets answering the state of `tick`, and what the skill is doing."""

    arm: str
    tick: int
    q: Floats
    dq: Floats
    gripper_opening: float
    task_id: int | None = None
    skill: str = "idle"
    progress: float = 0.0
    failure: str = ""
    request_seq: int = 0  # > 0 while the arm holds still for a grant of the move to `request_q_to` in `request_duration_s`
    request_q_to: Floats = ()
    request_duration_s: float = 0.0
    version: int = PROTOCOL_VERSION


class ArmStatus(Message, frozen=True, array_like=True):
    """Controller -> everyone, a heartbeat with what the arm is doing."""

    arm: str
    seq: int
    sim_time_s: float
    skill: str
    task_id: int | None
    progress: float
    busy_s: float = 0.0
    failure: str = ""
    incarnation: int = 0  # differs each time a controller starts: a restart is a loss and a rejoin
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
    events_published: int = 0  # line events the sim had published up to this tick: a reader knows if one is still on its way
    version: int = PROTOCOL_VERSION


class Assignment(Message, frozen=True, array_like=True, tag="assign"):
    """Coordinator -> controller: pick `part_id` from a surface and place it; `task_id` None cancels.

    `seq` counts this arm's orders (assignments and grants) from 1; states name the newest one
    (`ArmState.assign_seq`).
    """

    arm: str
    seq: int
    task_id: int | None
    part_id: int
    surface_z_m: float
    place_xyz: Floats
    surface_velocity: Floats
    version: int = PROTOCOL_VERSION


class MotionGrant(Message, frozen=True, array_like=True, tag="grant"):
    """Coordinator -> controller, on the assign key in the same `seq` count: the answer to motion request
    `request_seq`: `grant` (move now), or `deny` naming the arm in the way. A `wait` is not sent: the request
    stays with the coordinator, checked again at each decision."""

    arm: str
    seq: int
    request_seq: int
    decision: str
    conflict_arm: str = ""
    min_separation_m: float = -1.0
    version: int = PROTOCOL_VERSION


ArmOrder = Assignment | MotionGrant


class LineEvent(Message, frozen=True, array_like=True):
    """Sim -> coordinator: a part `arrived` (detail: feeder), came to rest `at_station` (detail: station),
    was `lost` (detail: why) or `retired` from a sink station (detail: station)."""

    kind: str
    part_id: int
    tick: int
    detail: str = ""
    type_index: int = 0
    version: int = PROTOCOL_VERSION


class CoordTick(Message, frozen=True, array_like=True):
    """Coordinator -> sim: decisions for `tick` are out; `assign_seqs` per arm, in scene order (used in lockstep)."""

    tick: int
    assign_seqs: tuple[int, ...]
    version: int = PROTOCOL_VERSION


class Progress(Message, frozen=True, array_like=True):
    """Coordinator -> launcher and monitor, a few times a second: the line's running totals."""

    sim_time_s: float
    parts_spawned: int
    parts_completed: int
    parts_missed: int
    busy_arms: int
    parts_failed: int = 0
    grants_denied: int = 0
    min_separation_m: float = -1.0  # the cell's closest approach so far; -1 before the first measure
    version: int = PROTOCOL_VERSION


class EStop(Message, frozen=True, array_like=True):
    """Anyone -> sim: engage (hold every arm within one tick) or release the emergency stop."""

    engaged: bool
    source: str
    version: int = PROTOCOL_VERSION


class SimControl(Message, frozen=True, array_like=True):
    """Anyone -> sim: pause or resume the clock, or change the realtime speed factor (None leaves a setting as it is)."""

    source: str
    paused: bool | None = None
    speed: float | None = None
    version: int = PROTOCOL_VERSION


class SimStatus(Message, frozen=True, array_like=True):
    """Sim -> monitor and anyone, a few times a second of wall time: the clock's settings and running figures.

    `utilisation` is per arm in scene order (fraction of ticks a skill was running);
    `latency_p99_ms` is over the latest round trips; `contact_pairs` are the arm pairs
    touching at the latest tick with a contact (`"arm_0-arm_1"`), at `last_contact_s`.
    """

    tick: int
    sim_time_s: float
    mode: str
    paused: bool
    estop: bool
    speed: float
    utilisation: Floats
    latency_p99_ms: float
    contact_ticks: int
    contact_pairs: tuple[str, ...] = ()
    last_contact_s: float = -1.0
    arms_lost: tuple[str, ...] = ()
    dropped_messages: int = 0
    version: int = PROTOCOL_VERSION


class Separations(Message, frozen=True, array_like=True):
    """Coordinator -> monitor, at its decision rate: each arm's nearest other arm, the distance and the
    closest points (world frame, flattened: a then b, 6 floats a pair), and the guard's margin."""

    sim_time_s: float
    arms_a: tuple[str, ...]
    arms_b: tuple[str, ...]
    distances_m: Floats
    points: Floats
    margin_m: float
    version: int = PROTOCOL_VERSION


class LineView(Message, frozen=True, array_like=True):
    """Sim -> monitors, every few ticks: every arm's state and the parts in one message (a viewer's decimated feed,
    so watching costs the line one message per `view_every_ticks` instead of one per arm per tick)."""

    tick: int
    sim_time_s: float
    arms: tuple[ArmState, ...]
    parts: PartsState
    version: int = PROTOCOL_VERSION


class RespawnRequest(Message, frozen=True, array_like=True):
    """Anyone -> launcher: start `arm`'s controller again if it died or went silent."""

    arm: str
    source: str
    version: int = PROTOCOL_VERSION


def separations_from_pairs(sim_time_s: float, pairs: list, margin_m: float) -> Separations:
    """A `Separations` message from the guard's nearest pairs (objects with a, b, distance_m, point_a, point_b)."""
    return Separations(
        sim_time_s, tuple(p.a for p in pairs), tuple(p.b for p in pairs), tuple(float(p.distance_m) for p in pairs),
        tuple(float(v) for p in pairs for v in (*p.point_a, *p.point_b)), margin_m,
    )


class EnvAction(Message, frozen=True, array_like=True):
    """PettingZoo env (`distributed=True`) -> one arm's process: a policy action to turn into joint targets,
    or (`kind` "reset") the arm's joints to start from. `seq` counts the env's requests."""

    arm: str
    seq: int
    kind: str  # "act" or "reset"
    values: Floats
    version: int = PROTOCOL_VERSION


class EnvTargets(Message, frozen=True, array_like=True):
    """One arm's process -> env: the joint targets and gripper opening for request `seq`."""

    arm: str
    seq: int
    q: Floats
    gripper_opening: float
    version: int = PROTOCOL_VERSION


MESSAGE_TYPES = (ArmState, ArmCommandMsg, ArmStatus, PartsState, Assignment, MotionGrant, LineEvent, CoordTick, Progress, EStop,
                 SimControl, SimStatus, Separations, LineView, RespawnRequest, EnvAction, EnvTargets)
