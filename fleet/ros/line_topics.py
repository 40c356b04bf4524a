"""The line's ROS topics from what the bus carries: the line's view (`world/view`: every arm and the parts in one
message, 25 Hz of sim time, as the monitors get it) gives `/joint_states` and `/tf` for every arm at once, as
joint_state_broadcaster and robot_state_publisher publish them, each arm's own joint states, the parts' markers
and the clock. Built only
for topics someone listens to (`wanted`), each message once for all its listeners, as rosbags typestore messages
(rosbridge sends them as JSON, rmw_zenoh as CDR), with `fleet.record.line_to_ros` (the recordings' own converter,
so a live line and its recording show the same frames and names)."""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState, CameraImage, GoalResultMsg, LineView
from fleet.record.camera_to_ros import camera_topic_types, live_messages
from fleet.record.line_to_ros import LineToRos
from fleet.record.ros_types import ros_type, time_msg
from fleet.ros import names
from fleet.ros.line_log import LineLog
from scenes.schema import Scene

VIEW_TOPICS = frozenset({names.JOINT_STATES, names.TF, names.PARTS, names.CLOCK})


class RateCap:
    """At most `hz` messages per wall second per stream (0: no cap): a watcher of a lockstep line running at ten
    times real time gets its newest moments, not ten times what it can draw."""

    def __init__(self, hz: float) -> None:
        self.period_s = 1.0 / hz if hz > 0 else 0.0
        self._last: dict[str, float] = {}

    def admits(self, stream: str) -> bool:
        if not self.ready(stream):
            return False
        self._last[stream] = time.monotonic()
        return True

    def ready(self, stream: str) -> bool:
        """Whether `stream` may have its next message now (nothing recorded)."""
        return time.monotonic() - self._last.get(stream, -math.inf) >= self.period_s


class LineTopics:
    """One scene's topics, message by message; `latched` keeps what a late subscriber gets at once. Views and each
    arm's states are turned into topics at most `max_rate_hz` times a wall second (`RateCap`)."""

    def __init__(self, scene: Scene, max_rate_hz: float = names.DEFAULT_MAX_RATE_HZ) -> None:
        self.ros = LineToRos(scene)
        self.arms = [a.name for a in scene.arms]
        self.types = names.line_topics(self.arms)
        self.cameras = {c.name: list(c.images) for c in scene.cameras}
        for camera, kinds in self.cameras.items():
            self.types |= camera_topic_types(camera, kinds)
        self._camera_ticks: dict[str, int] = {}
        self.clock_s = -1.0
        self.log = LineLog()  # `/rosout`
        self.latched = {names.TF_STATIC: self.ros.tf_static(), names.CELL: self.ros.cell_markers()}
        self.cap = RateCap(max_rate_hz)
        self._held_view: LineView | None = None  # the newest view the cap held back (`held_back`)

    def keys_needed(self, keys: Keys, wanted: set[str], driven: set[str]) -> set[str]:
        """The bus keys a front end needs now (`OnDemandSubscriptions`): the states of the arms its clients' goals
        drive (`driven`: their actions follow them), the line's view while a topic it feeds is (an arm's own joint
        states too: the view carries every arm's state, and hearing each arm's own key as well cost a lockstep
        line about a fifth of its speed), a camera's images while one of its topics is."""
        own = {names.arm_joint_states(a) for a in self.arms}
        viewed = wanted & (VIEW_TOPICS | own | {names.ROSOUT})  # the log follows every arm's state in the view
        needed = {keys.arm_state(a) for a in driven} | ({keys.view} if viewed else set())
        for camera, kinds in self.cameras.items():
            if wanted & set(camera_topic_types(camera, kinds)):
                needed |= {keys.camera(camera, kind) for kind in kinds}
        return needed

    def from_camera(self, image: CameraImage, wanted: set[str]) -> list[tuple[str, object]]:
        """The topics one camera image feeds, among those `wanted` (each camera at most `max_rate_hz` frames a wall
        second)."""
        if image.camera not in self.cameras or image.kind not in self.cameras[image.camera]:
            return []
        first = image.tick != self._camera_ticks.get(image.camera)
        if first:
            if not self.cap.admits(f"camera/{image.camera}"):
                return []
            self._camera_ticks[image.camera] = image.tick
        try:
            return live_messages(image, wanted, first)
        except ValueError:  # an image that is not what it says: nothing to show
            return []

    def from_result(self, result: GoalResultMsg, wanted: set[str]) -> list[tuple[str, object]]:
        """The log entry of a goal result (one the plant refused or aborted), if `/rosout` is `wanted`."""
        entry = self.log.from_result(result, self.clock_s) if names.ROSOUT in wanted else None
        return [(names.ROSOUT, entry)] if entry is not None else []

    def from_view(self, view: LineView, wanted: set[str]) -> list[tuple[str, object]]:
        """The topics the line's view feeds (every arm's joints and links, the parts, the clock), among those
        `wanted`; the log's entries of every view, however many the rate cap lets through."""
        logged = self.log.from_states(list(view.arms), view.sim_time_s) if names.ROSOUT in wanted else []
        out: list[tuple[str, object]] = [(names.ROSOUT, entry) for entry in logged]
        if not self.cap.admits("view"):
            self._held_view = view
            return out
        self._held_view = None
        arms = [s for s in view.arms if s.arm in self.ros.arms]
        if view.sim_time_s > self.clock_s:
            self.clock_s = view.sim_time_s
            if names.CLOCK in wanted:
                out.append((names.CLOCK, ros_type("rosgraph_msgs/msg/Clock")(clock=time_msg(view.sim_time_s))))
        if names.JOINT_STATES in wanted and arms:
            out.append((names.JOINT_STATES, self._all_joints(arms)))
        out += [(t, self.ros.joint_state(s)) for s in arms if (t := names.arm_joint_states(s.arm)) in wanted]
        if names.TF in wanted and arms:
            out.append((names.TF, self.ros.tf(arms)))
        if names.PARTS in wanted:
            out.append((names.PARTS, self.ros.parts_markers(view.parts)))
        return out

    def held_back(self, wanted: set[str]) -> list[tuple[str, object]]:
        """The topics of the newest view the rate cap held back, once the cap lets it through: when the line stops
        or pauses, its watchers see where it stands, not a moment up to a period before (its log is already out)."""
        if self._held_view is None or not self.cap.ready("view"):
            return []
        return self.from_view(self._held_view, wanted - {names.ROSOUT})

    def _all_joints(self, states: list[ArmState]):
        """One `JointState` of every arm's joints, named `<arm>/<joint>`, stamped with the view's time."""
        each = [self.ros.joint_state(s) for s in states]
        return dataclasses.replace(
            each[0],
            name=[f"{s.arm}/{n}" for s, m in zip(states, each) for n in m.name],
            position=np.concatenate([m.position for m in each]),
            velocity=np.concatenate([m.velocity for m in each]),
        )
