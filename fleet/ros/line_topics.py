"""The line's ROS topics from what the bus carries: an arm's state gives its joint states, its links' TF and the
clock; the parts give markers. Built only for topics someone listens to (`wanted`), each message once for all
its listeners, as rosbags typestore messages (rosbridge sends them as JSON, rmw_zenoh as CDR), with
`fleet.record.line_to_ros` (the recordings' own converter, so a live line and its recording show the same frames
and names)."""

from __future__ import annotations

import dataclasses

from fleet.bus.messages import ArmState, PartsState
from fleet.record.line_to_ros import LineToRos
from fleet.record.ros_types import ros_type, time_msg
from fleet.ros import names
from scenes.schema import Scene


class LineTopics:
    """One scene's topics, message by message; `latched` keeps what a late subscriber gets at once."""

    def __init__(self, scene: Scene) -> None:
        self.ros = LineToRos(scene)
        self.arms = [a.name for a in scene.arms]
        self.types = names.line_topics(self.arms)
        self.clock_s = -1.0
        self.latched = {names.TF_STATIC: self.ros.tf_static(), names.CELL: self.ros.cell_markers()}

    def from_state(self, state: ArmState, wanted: set[str]) -> list[tuple[str, object]]:
        """The topics one arm state feeds, among those `wanted`."""
        if state.arm not in self.ros.arms:
            return []
        out = []
        own = names.arm_joint_states(state.arm)
        if own in wanted or names.JOINT_STATES in wanted:
            joints = self.ros.joint_state(state)
            if own in wanted:
                out.append((own, joints))
            if names.JOINT_STATES in wanted:
                prefixed = [f"{state.arm}/{n}" for n in joints.name]
                out.append((names.JOINT_STATES, dataclasses.replace(joints, name=prefixed)))
        if names.TF in wanted:
            out.append((names.TF, self.ros.tf([state])))
        if state.sim_time_s > self.clock_s:
            self.clock_s = state.sim_time_s
            if names.CLOCK in wanted:
                out.append((names.CLOCK, ros_type("rosgraph_msgs/msg/Clock")(clock=time_msg(state.sim_time_s))))
        return out

    def from_parts(self, parts: PartsState, wanted: set[str]) -> list[tuple[str, object]]:
        return [(names.PARTS, self.ros.parts_markers(parts))] if names.PARTS in wanted else []
