"""What a recording holds, from the bus messages heard: every raw message on its key's channel, and the ROS 2
topics derived from them. No I/O but the writer: the recorder node feeds it what it hears.

TF comes from the sim's frames (every arm at one tick, at the coordinator's rate: 10 Hz), joint states from each
arm's own states (its controller's rate: 20 Hz). Stamps are sim time: a message's own (`sim_time_s`, or its tick) where
it carries one, else the newest sim time
heard before it (goals, orders, e-stops), so nothing is stamped before the message that caused it.
"""

from __future__ import annotations

import json
import logging
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import (
    ArmGoalMsg,
    ArmOrder,
    ArmState,
    ArmStatus,
    Assignment,
    CameraImage,
    ControllerStep,
    CoordTick,
    EnvAction,
    EnvTargets,
    EStop,
    GoalResultMsg,
    GripperGoalMsg,
    LineEvent,
    LineView,
    MotionGrant,
    PartDetections,
    PartsState,
    Progress,
    RespawnRequest,
    Roster,
    Separations,
    SimControl,
    SimStatus,
    TrajectoryGoalMsg,
)
from fleet.record.camera_to_ros import camera_topics
from fleet.record.forked_build import LaterInChild, serialized
from fleet.record.line_to_ros import LineToRos
from fleet.record.mcap_file import SNAPSHOT_MEDIA_TYPE, RecordingWriter
from fleet.record.ros_types import ros_type, sim_ns, to_ros
from fleet.snapshot.snapshot_file import SnapshotError, parse_snapshot
from scenes.schema import Scene

log = logging.getLogger("clawfleet.record")

ARM_LEAVES = {
    "state": ArmState,
    "step": ControllerStep,
    "goal": ArmGoalMsg,
    "drive": ArmGoalMsg,
    "result": GoalResultMsg,
    "status": ArmStatus,
    "assign": ArmOrder,
    "env_action": EnvAction,
    "env_targets": EnvTargets,
}
LINE_LEAVES = {
    "world/parts": PartsState,
    "seen/parts": PartsState,  # perception's (`fleet run --perception cameras`)
    "world/events": LineEvent,
    "world/control": SimControl,
    "world/status": SimStatus,
    "world/frame": LineView,
    "estop": EStop,
    "coord/tick": CoordTick,
    "coord/progress": Progress,
    "coord/separation": Separations,
    "launcher/respawn": RespawnRequest,
    "launcher/roster": Roster,
}
SEMANTIC_TOPICS = {  # bus message type -> ROS topic (arm ones under /<arm>)
    LineEvent: "/line/events",
    TrajectoryGoalMsg: "trajectory_goals",
    GripperGoalMsg: "gripper_goals",
    GoalResultMsg: "goal_results",
    Assignment: "assignments",
    MotionGrant: "grants",
    ArmStatus: "status",
    Progress: "/line/progress",
    SimStatus: "/line/sim_status",
    Separations: "/line/separations",
}


PARALLEL_AT_LEAST = 2000  # ROS messages to build before a second process pays for its start
OWN_SHARE = 0.4  # of them built here (this process also writes every record), the rest in the forked child


@dataclass
class Heard:
    """One heard bus message, decoded and stamped: the raw record, and the ROS topics it feeds (topic, maker)."""

    key: str
    message_type: str
    payload: bytes
    stamp_ns: int
    derived: list[tuple[str, Callable[[], object]]] = field(default_factory=list)


@dataclass
class RecorderStats:
    by_key: Counter = field(default_factory=Counter)
    undecodable: int = 0


class Recorder:
    """Turns heard bus messages into a recording: `take(key, payload)` for each, `finish(summary)` at the end.
    When to take them (as they come, or once the line is quiet) is the recorder node's choice."""

    def __init__(self, writer: RecordingWriter, scene: Scene, keys: Keys) -> None:
        self.writer = writer
        self.ros = LineToRos(scene)
        self.cameras = {c.name for c in scene.cameras}
        self.control_hz = scene.control_hz
        self.drops = DropCounter()
        self.stats = RecorderStats()
        self.now_s = 0.0
        self._prefix = f"{keys.prefix}/"
        self._decoders: dict[type, Decoder] = {}
        self._last_tick: dict[str, int] = {}  # per arm ("" for the line's frames): the newest tick made into ROS topics
        self._write_static()

    def _write_static(self) -> None:
        self.writer.ros("/tf_static", self.ros.tf_static(), 0, latched=True)
        self.writer.ros("/cell", self.ros.cell_markers(), 0, latched=True)
        description = ros_type("std_msgs/msg/String")
        for arm in self.ros.arms.values():
            self.writer.ros(f"/{arm.arm}/robot_description", description(data=arm.spec.urdf_text()), 0, latched=True)

    def message_type(self, key: str) -> type | None:
        """The bus message type a key carries (None: a key this recorder does not know)."""
        if not key.startswith(self._prefix):
            return None
        rest = key[len(self._prefix) :]
        if rest.startswith("arm/"):
            return ARM_LEAVES.get(rest.rsplit("/", 1)[-1])
        if rest.startswith("camera/") and rest.count("/") == 2:
            return CameraImage
        if rest.startswith("perception/") and rest.count("/") == 1:
            return PartDetections
        return LINE_LEAVES.get(rest)

    def _decode(self, key: str, message_type: type | None, payload: bytes):
        if message_type is None:
            return None
        if message_type not in self._decoders:
            self._decoders[message_type] = Decoder(message_type, self.drops)
        return self._decoders[message_type].decode(key, payload)

    def _stamp_s(self, message: object) -> float:
        """The message's own sim time where it has one, else the newest heard."""
        if isinstance(
            message,
            (
                ArmState,
                LineView,
                PartsState,
                GoalResultMsg,
                ArmStatus,
                Progress,
                SimStatus,
                Separations,
                CameraImage,
                PartDetections,
            ),
        ):
            return message.sim_time_s
        if isinstance(message, (LineEvent, ControllerStep, CoordTick)):
            return message.tick / self.control_hz
        return self.now_s

    def take(self, key: str, payload: bytes) -> None:
        """Record one heard message: raw (always, even one that does not decode), and its ROS topics."""
        heard = self._plan(key, payload)
        self._write(heard, [serialized(make) for _, make in heard.derived])

    def take_all(self, messages: list[tuple[str, bytes]], workers: int = 1) -> None:
        """Record many heard messages (the same file as `take` on each, to the byte). With `workers` > 1 and enough
        of them, a forked process builds and serialises the later ROS topics while this one does the earlier."""
        planned = [self._plan(key, payload) for key, payload in messages]
        makers = [make for heard in planned for _, make in heard.derived]
        split = len(makers) if workers <= 1 or len(makers) < PARALLEL_AT_LEAST else round(len(makers) * OWN_SHARE)
        with LaterInChild(makers, split) as later:
            built = [serialized(make) for make in makers[:split]]
            at = 0
            for heard in planned:
                n = len(heard.derived)
                while at + n > len(built):
                    built += later.collect()
                self._write(heard, built[at : at + n])
                at += n

    def _plan(self, key: str, payload: bytes) -> Heard:
        """Decode and stamp one message, and say which ROS topics it makes (built later: `serialized`)."""
        message_type = self.message_type(key)
        message = self._decode(key, message_type, payload)
        stamp_s = self._stamp_s(message) if message is not None else self.now_s
        self.now_s = max(self.now_s, stamp_s)
        type_name = getattr(type(message), "__name__", "") if message is not None else ""
        heard = Heard(key, type_name or getattr(message_type, "__name__", "") or "unknown", payload, sim_ns(stamp_s))
        self.stats.by_key[key] += 1
        if message is None:
            self.stats.undecodable += 1
        else:
            heard.derived = self._derived(message, heard.key)
        return heard

    def _write(self, heard: Heard, built: list[tuple[str, bytes]]) -> None:
        self.writer.raw(heard.key, heard.message_type, heard.payload, heard.stamp_ns)
        for (topic, _), (typename, data) in zip(heard.derived, built):
            self.writer.ros_bytes(topic, typename, data, heard.stamp_ns)

    def _is_new(self, stream: str, tick: int) -> bool:
        """A state or frame not seen before (the sim re-sends one while it waits for its answer)."""
        if tick <= self._last_tick.get(stream, -1):
            return False
        self._last_tick[stream] = tick
        return True

    def _derived(self, message: object, key: str = "") -> list[tuple[str, Callable[[], object]]]:
        """(topic, what makes its ROS message) for each ROS topic this bus message feeds (`key`: where it was
        heard)."""
        out: list[tuple[str, Callable[[], object]]] = []
        if isinstance(message, ArmState) and message.arm in self.ros.arms and self._is_new(message.arm, message.tick):
            out.append((f"/{message.arm}/joint_states", partial(self.ros.joint_state, message)))
        elif isinstance(message, LineView) and self._is_new("", message.tick):
            out.append(("/tf", partial(self.ros.tf, [a for a in message.arms if a.arm in self.ros.arms])))
            out.append(("/parts", partial(self.ros.parts_markers, message.parts)))
        elif isinstance(message, PartsState) and key.endswith("/seen/parts") and self._is_new("seen", message.tick):
            out.append(("/seen/parts", partial(self.ros.parts_markers, message)))  # the parts as the line saw them
        elif isinstance(message, CameraImage) and message.camera in self.cameras:
            out += camera_topics(message, self._is_new(f"camera/{message.camera}", message.tick))
        topic = SEMANTIC_TOPICS.get(type(message))
        if topic is not None:
            out.append((topic if topic.startswith("/") else f"/{message.arm}/{topic}", partial(to_ros, message)))
        return out

    def finish(self, summary: dict | None) -> None:
        """The run's summary (latched, at the last sim time heard) and the snapshots it lists (attached at their sim
        times: a replay can branch from them), then the file's index."""
        if summary is not None:
            w = self.writer
            w.ros(
                "/line/summary",
                ros_type("std_msgs/msg/String")(data=json.dumps(summary, sort_keys=True)),
                sim_ns(self.now_s),
                latched=True,
            )
            for path in summary.get("snapshots") or []:
                self.carry_snapshot(Path(path))
        self.writer.close()

    def carry_snapshot(self, path: Path) -> None:
        """A snapshot file of the run, attached at its sim time (one that cannot be read is left out, and said)."""
        try:
            data = path.read_bytes()
            snapshot = parse_snapshot(data, path)
        except (OSError, SnapshotError) as exc:
            log.warning("the recording leaves out a snapshot: %s", exc)
            return
        self.writer.attach(path.name, data, sim_ns(snapshot.sim_time_s), SNAPSHOT_MEDIA_TYPE)
