"""Every message on the bus, typed with a protocol version, encoded as compact MessagePack.

Messages are msgspec Structs: frozen, typed dataclass-like records that encode
as MessagePack arrays (no field names on the wire) and decode with type checks.

Joint vectors are tuples of floats in the arm spec's joint order; poses are
world frame, metres, quaternions wxyz (docs/conventions.md). `docs/protocol.md`
lists which key carries which message.
"""

from __future__ import annotations

import msgspec

from robots.phase import Phase

PROTOCOL_VERSION = 12  # 11: part detections (`PartDetections`); 12: images name the events before them
Floats = tuple[float, ...]


class Message(msgspec.Struct, frozen=True, array_like=True):
    """Base of all bus messages."""


class ArmState(Message, frozen=True, array_like=True):
    """Sim -> its controller at the controller's rate (and, in `LineView`s, to the coordinator and monitors):
    one arm's joints, gripper and tool pose, with its tracker's feedback.

    Feedback (FollowJointTrajectory's): `goal_id` is the trajectory goal driving the arm (0: none, it holds),
    `desired_q`/`desired_dq` where the tracker wants it now (error = desired - actual `q`); `result_*` is the
    newest trajectory result (`GoalResultMsg` carries every result). `task_id`, `phase` and `progress` echo
    the controller's last step, so the coordinator learns what each arm does in step with the sim clock.
    `assign_seq` is the newest order the coordinator had published to this arm when this tick began: a
    controller acts on an order at the first state announcing it (lockstep with a coordinator; -1 otherwise:
    act on arrival). `next_tick` is when this arm's controller gets its next state; its answer takes effect
    `period_ticks` later (lockstep applies answers at the arm's next due tick). `held` is true while the
    arm is held (e-stop, watchdog, lost controller, an outside driver); `lost` once its controller went silent in
    lockstep; `taken` while an outside client (ROS, on the arm's `drive` key) drives it: its controller waits and
    the coordinator gives it nothing until it is let go.
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
    phase: str = Phase.IDLE.value  # the skill's `robots.phase.Phase`
    progress: float = 0.0
    assign_seq: int = 0
    failure: str = ""
    failure_code: str = ""  # `robots.failures.FailureCode` of `failure` ("" when none)
    request_seq: int = 0  # echo of the controller's motion request (see ControllerStep)
    request_q_to: Floats = ()
    request_duration_s: float = 0.0
    request_then_q: Floats = ()
    request_then_after_s: Floats = ()
    goal_id: int = 0
    desired_q: Floats = ()
    desired_dq: Floats = ()
    result_goal_id: int = 0
    result_status: str = ""
    result_code: int = 0
    result_reason: str = ""
    next_tick: int = 0
    period_ticks: int = 0  # the controller's period: its answer to the state at `next_tick` takes effect a period later
    delivered_tick: int = -1  # the tick this copy reached its controller (its own clock; -1: `tick`, no network delay)
    taken: bool = False
    snapshot_tick: int = -1  # the tick of the run's next snapshot (-1: none due): from it on, hold what comes
    version: int = PROTOCOL_VERSION


class ControllerStep(Message, frozen=True, array_like=True):
    """Controller -> sim: the answer to the state of `tick`: when it wants its next state (`next_tick`), the ids
    of the goals it sent with this answer (the sim waits for them in lockstep), and what the skill is doing (its
    phase)."""

    arm: str
    tick: int
    next_tick: int
    goal_ids: tuple[int, ...] = ()
    task_id: int | None = None
    phase: str = Phase.IDLE.value
    progress: float = 0.0
    failure: str = ""
    failure_code: str = ""
    # > 0 while the arm holds still for a grant of the move to `request_q_to` in `request_duration_s`
    request_seq: int = 0
    request_q_to: Floats = ()
    request_duration_s: float = 0.0
    # the local stage after the move, which asks no grant of its own: poses (flattened, one row per joint vector)
    # reached these many seconds after the move's end (increasing); the grant covers them too
    request_then_q: Floats = ()
    request_then_after_s: Floats = ()
    version: int = PROTOCOL_VERSION


class TrajectoryGoalMsg(Message, frozen=True, array_like=True, tag="trajectory"):
    """The arm's controller (on `goal`) or an outside client (on `drive`) -> sim: follow a joint trajectory
    (control_msgs/FollowJointTrajectory).

    `joint_names` are the arm's own; `positions` (and optional `velocities`, `accelerations`) are flattened,
    one row of len(joint_names) per point, at strictly increasing `times_from_start_s` after `start_time_s`
    (sim seconds; None: when the sim receives it). Tolerances: empty (not checked), one value, or one per joint;
    0 = not checked. A newer goal preempts this one at its own start time.
    """

    arm: str
    goal_id: int
    joint_names: tuple[str, ...]
    times_from_start_s: Floats
    positions: Floats
    velocities: Floats = ()
    accelerations: Floats = ()
    start_time_s: float | None = None
    path_tolerance_rad: Floats = ()
    goal_tolerance_rad: Floats = ()
    goal_time_tolerance_s: float = 0.5
    version: int = PROTOCOL_VERSION


class GripperGoalMsg(Message, frozen=True, array_like=True, tag="gripper"):
    """Anyone (the arm's controller) -> sim: drive the claw to `opening` (0 closed, 1 open) with at most
    `max_effort_n` (0: the robot's own limit) from `start_time_s` (None: on receipt); GripperCommand-like."""

    arm: str
    goal_id: int
    opening: float
    max_effort_n: float = 0.0
    start_time_s: float | None = None
    version: int = PROTOCOL_VERSION


ArmGoalMsg = TrajectoryGoalMsg | GripperGoalMsg


class GoalResultMsg(Message, frozen=True, array_like=True):
    """Sim -> anyone, once per goal: `status` succeeded / aborted / rejected / preempted, control_msgs' `code`
    (0 SUCCESSFUL, -1 INVALID_GOAL, -2 INVALID_JOINTS, -4 PATH_TOLERANCE_VIOLATED, -5 GOAL_TOLERANCE_VIOLATED;
    -6 a safety stop: e-stop, watchdog, lost controller), the reason, and for the claw `reached` / `stalled`."""

    arm: str
    goal_id: int
    kind: str
    status: str
    code: int
    reason: str
    sim_time_s: float
    reached: bool = False
    stalled: bool = False
    version: int = PROTOCOL_VERSION


class ArmStatus(Message, frozen=True, array_like=True):
    """Controller -> everyone, a heartbeat with what the arm is doing."""

    arm: str
    seq: int
    sim_time_s: float
    phase: str
    task_id: int | None
    progress: float
    busy_s: float = 0.0
    failure: str = ""
    incarnation: int = 0  # differs each time a controller starts: a restart is a loss and a rejoin
    part_id: int = -1  # the assignment it works on or holds, when it has one (a respawned coordinator adopts it)
    place_xyz: Floats = ()
    assign_seq: int = -1  # the newest order it received (a respawned coordinator counts on from it)
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
    # line events the sim had published up to this tick: a reader knows if one is still on its way
    events_published: int = 0
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
    holder: int = 0  # the incarnation of the coordinator that gave it (0: not said); see `Roster`
    decision_tick: int = -1  # the tick of the frame whose decision gave it (-1: not said)
    version: int = PROTOCOL_VERSION


class MotionGrant(Message, frozen=True, array_like=True, tag="grant"):
    """Coordinator -> controller, on the assign key in the same `seq` count: the answer to motion request
    `request_seq`: `grant` (move now), `deny` naming the arm in the way, or `standby` (a transfer to a
    fixture that is not ready yet: wait beside it, then ask again). A `wait` is not sent: the request stays
    with the coordinator, checked again at each decision."""

    arm: str
    seq: int
    request_seq: int
    decision: str
    conflict_arm: str = ""
    min_separation_m: float = -1.0
    start_time_s: float = -1.0  # sim time the granted move starts (the arm's next state); -1: when heard
    holder: int = 0  # the incarnation of the coordinator that gave it (0: not said); see `Roster`
    decision_tick: int = -1  # the tick of the frame whose decision gave it (-1: not said)
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


class EventLog(Message, frozen=True, array_like=True):
    """Sim -> a coordinator that asks (`Keys.history`): every line event published so far, in order, as of `tick`.
    A respawned coordinator rebuilds its ledger from it."""

    tick: int
    events: tuple[LineEvent, ...]
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
    """Anyone -> sim: pause or resume the clock, change the realtime speed factor (None leaves a setting as it
    is), or take a snapshot of the run at the next tick boundary (`snapshot`)."""

    source: str
    paused: bool | None = None
    speed: float | None = None
    snapshot: bool = False
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
    """Sim -> monitors (`world/view`, every few ticks while watched) and the coordinator (`world/frame`, at its
    decision rate): every arm's state and the parts in one message."""

    tick: int
    sim_time_s: float
    arms: tuple[ArmState, ...]
    parts: PartsState
    delivered_tick: int = -1  # the tick this copy reached the coordinator (-1: `tick`, no network delay)
    snapshot_tick: int = -1  # the tick of the run's next snapshot (-1: none due): from it on, hold what comes
    version: int = PROTOCOL_VERSION


class Roster(Message, frozen=True, array_like=True):
    """Launcher -> everyone, on every start of a node and every second: the incarnation of each node it started
    (`nodes[i]` is in its `incarnations[i]`th start). A node's incarnation changes only through the launcher, so a
    heartbeat or an order naming another one is a lie or a ghost, refused and counted."""

    nodes: tuple[str, ...]
    incarnations: tuple[int, ...]
    version: int = PROTOCOL_VERSION

    def of(self, node: str) -> int | None:
        """The incarnation the launcher started `node` in, None if it names no such node."""
        return dict(zip(self.nodes, self.incarnations)).get(node)


class RespawnRequest(Message, frozen=True, array_like=True):
    """Anyone -> launcher: start `arm`'s controller again if it died or went silent."""

    arm: str
    source: str
    version: int = PROTOCOL_VERSION


class SnapshotAsk(Message, frozen=True, array_like=True):
    """Sim -> nodes, at a tick boundary with every answer in: send your state as of `tick`: the coordinator (`node`
    "coordinator") once it has every line event published so far (`events`), the controllers (`node`
    "controllers") each once it has the orders the coordinator sent it (`orders`, by arm in the scene's order) and
    the parts message of `parts_tick` (-1: none yet). Lockstep asks both at once and goes on (each node, told of
    `tick` ahead by `snapshot_tick`, holds what it is sent from then on); realtime asks the coordinator first."""

    tick: int
    node: str
    events: int = 0
    orders: tuple[int, ...] = ()
    parts_tick: int = -1
    version: int = PROTOCOL_VERSION


class SnapshotPart(Message, frozen=True, array_like=True):
    """Node -> sim: its state for the snapshot of `tick` (`state`, zlib-compressed, opaque to everyone but the
    node), or why it has none (`error`); the coordinator adds the newest order it sent each arm (`orders`, scene
    order). Sent again with `restored` and no state by a node started from a snapshot, once it has put its state
    back."""

    node: str
    tick: int
    state: bytes = b""
    error: str = ""
    orders: tuple[int, ...] = ()
    restored: bool = False
    incarnation: int = 0  # which start of the node this is (a restored run starts it in the same)
    version: int = PROTOCOL_VERSION


def wire_layout(message_type: type[Message]) -> str:
    """How `message_type` goes on the wire: one MessagePack array, its tag first where it has one, then its fields
    in this order (trailing fields with defaults may be left out). `docs/protocol.md` lists every type's."""
    tag = message_type.__struct_config__.tag
    fields = [f"{name}" for name in message_type.__struct_fields__]
    return f"`{message_type.__name__}`: [{', '.join(([repr(tag)] if tag else []) + fields)}]"


def separations_from_pairs(sim_time_s: float, pairs: list, margin_m: float) -> Separations:
    """A `Separations` message from the guard's nearest pairs (objects with a, b, distance_m, point_a, point_b)."""
    return Separations(
        sim_time_s,
        tuple(p.a for p in pairs),
        tuple(p.b for p in pairs),
        tuple(float(p.distance_m) for p in pairs),
        tuple(float(v) for p in pairs for v in (*p.point_a, *p.point_b)),
        margin_m,
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


class CameraImage(Message, frozen=True, array_like=True):
    """Sim -> anyone, at the camera's rate in sim time: one image one camera made (`kind`: rgb, depth or
    segmentation), `encoding` as `fleet.bus.images` says (png, jpeg or raw for RGB; raw float32 metres or
    png16 millimetres for depth; raw or zlib int32 for segmentation). `intrinsics` is K row by row; the camera's
    optical frame (+z forward, +x right, +y down) stands at `position_m` with `quaternion_wxyz` in the world."""

    camera: str
    kind: str
    tick: int
    sim_time_s: float
    width_px: int
    height_px: int
    encoding: str
    data: bytes
    intrinsics: Floats
    position_m: Floats
    quaternion_wxyz: Floats
    events_published: int = 0  # line events the sim had published by this frame (perception waits for them)
    version: int = PROTOCOL_VERSION


class PartDetections(Message, frozen=True, array_like=True):
    """Perception -> anyone, for each of a camera's frames: the parts it believes are there (`docs/perception.md`),
    as tracks carried from frame to frame: each track's id, kind (`fleet.sim.cameras.part_looks`), top face's centre
    (world, x y z after one another), yaw of its longer side, confidence and the sim time it was last seen (a track
    hidden in this frame keeps the spot it was seen at). `tick` and `sim_time_s` are the frame's."""

    camera: str
    tick: int
    sim_time_s: float
    track_ids: tuple[int, ...]
    kinds: tuple[int, ...]
    top_centres_m: Floats
    yaws_rad: Floats
    confidences: Floats
    seen_s: Floats
    version: int = PROTOCOL_VERSION


MESSAGE_TYPES = (
    ArmState,
    ControllerStep,
    TrajectoryGoalMsg,
    GripperGoalMsg,
    GoalResultMsg,
    ArmStatus,
    PartsState,
    Assignment,
    MotionGrant,
    LineEvent,
    CoordTick,
    Progress,
    EStop,
    SimControl,
    SimStatus,
    Separations,
    LineView,
    RespawnRequest,
    Roster,
    EnvAction,
    EnvTargets,
    SnapshotAsk,
    SnapshotPart,
    CameraImage,
    PartDetections,
)
