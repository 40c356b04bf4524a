"""One line action natively on rmw_zenoh, as rcl_action lays an action out: the services
`<action>/_action/send_goal`, `cancel_goal` and `get_result`, the topics `_action/feedback` and `_action/status`
(TRANSIENT_LOCAL). Goals are followed by the line's one `LineActions` (the same as rosbridge's).

A goal is answered `accepted` once the arm starts it (or the sim has not refused it within `ACCEPT_WITHIN_S`);
one the line refuses (unreadable, unknown joints, an unsafe path) is not accepted, as ros2_controllers' joint
trajectory controller rejects it. Results wait for `get_result`; finished goals are kept `KEEP_RESULTS_S`.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field

from fleet.ros import trajectory_action as fjt
from fleet.ros.line_actions import GoalReplies, LineActions
from fleet.ros.rmw_zenoh import Ros2Node, Ros2Request
from fleet.ros.ros_json import from_json, time_json, to_json

ACCEPT_WITHIN_S = 0.5  # wall seconds: a goal the sim has neither started nor refused by then is accepted
KEEP_RESULTS_S = 60.0  # wall seconds a finished goal's result can still be asked for
ACCEPTED, EXECUTING, CANCELING = 1, 2, 3  # action_msgs/msg/GoalStatus
CANCEL_NONE, CANCEL_UNKNOWN_GOAL, CANCEL_TERMINATED = 0, 2, 3  # action_msgs/srv/CancelGoal return codes


@dataclass
class NativeGoal:
    uuid: bytes
    stamp_s: float  # when it was sent (sim time, as the line knows it)
    asked_at: float  # wall clock
    send_request: Ros2Request | None  # answered once the goal is accepted or refused
    status: int = ACCEPTED
    result: fjt.ActionResult | None = None
    finished_at: float = 0.0
    result_requests: list[Ros2Request] = field(default_factory=list)


class NativeAction:
    """One action (`/<arm>/follow_joint_trajectory` or `/<arm>/gripper_cmd`) served on a ROS 2 node."""

    def __init__(self, node: Ros2Node, name: str, action_type: str, actions: LineActions, wake: threading.Event):
        self.name, self.action_type, self.actions = name, action_type, actions
        self.send_goal = node.service(f"{name}/_action/send_goal", f"{action_type}_SendGoal", wake)
        self.cancel_goal = node.service(f"{name}/_action/cancel_goal", "action_msgs/srv/CancelGoal", wake)
        self.get_result = node.service(f"{name}/_action/get_result", f"{action_type}_GetResult", wake)
        self.feedback = node.publisher(f"{name}/_action/feedback", f"{action_type}_FeedbackMessage")
        self.status = node.publisher(f"{name}/_action/status", "action_msgs/msg/GoalStatusArray", latched=True)
        self.goals: dict[bytes, NativeGoal] = {}
        self.refused = 0

    @property
    def unreadable(self) -> int:
        return sum(s.unreadable for s in (self.send_goal, self.cancel_goal, self.get_result))

    def poll(self, sim_time_s: float) -> None:
        """Answer what was asked since the last poll; accept goals the sim kept quiet about; forget old ones."""
        for request in self.send_goal.take():
            self._on_send_goal(request, sim_time_s)
        for request in self.cancel_goal.take():
            self._on_cancel(request)
        for request in self.get_result.take():
            self._on_get_result(request)
        now = time.monotonic()
        for goal in list(self.goals.values()):
            if goal.send_request is not None and now - goal.asked_at >= ACCEPT_WITHIN_S:
                self._accept(goal)
            elif goal.result is not None and now - goal.finished_at >= KEEP_RESULTS_S:
                del self.goals[goal.uuid]

    # --- the three services -----------------------------------------------------------
    def _on_send_goal(self, request: Ros2Request, sim_time_s: float) -> None:
        uuid = bytes(request.message.goal_id.uuid)
        if uuid in self.goals:
            self._answer_send(request, False, sim_time_s)  # a goal id is used once
            return
        goal = NativeGoal(uuid, sim_time_s, time.monotonic(), request)
        self.goals[uuid] = goal
        replies = GoalReplies(
            result=lambda r: self._finished(goal, r),
            feedback=lambda values: self._publish_feedback(goal, values),
            started=lambda: self._accept(goal, EXECUTING),
        )
        self.actions.send(self, uuid, self.name, to_json(request.message.goal), replies)

    def _on_cancel(self, request: Ros2Request) -> None:
        info = request.message.goal_info
        uuid = bytes(info.goal_id.uuid)
        every = not any(uuid) and info.stamp.sec == 0 and info.stamp.nanosec == 0  # zero id and stamp: all goals
        targets = [g for g in self.goals.values() if every or g.uuid == uuid]
        canceling = [g for g in targets if g.result is None and self.actions.cancel(self, g.uuid)]
        for goal in canceling:
            goal.status = CANCELING
        code = CANCEL_NONE if canceling else CANCEL_TERMINATED if targets else CANCEL_UNKNOWN_GOAL
        infos = [{"goal_id": {"uuid": list(g.uuid)}, "stamp": time_json(g.stamp_s)} for g in canceling]
        request.reply(from_json("action_msgs/srv/CancelGoal_Response", {"return_code": code, "goals_canceling": infos}))
        if canceling:
            self._publish_status()

    def _on_get_result(self, request: Ros2Request) -> None:
        goal = self.goals.get(bytes(request.message.goal_id.uuid))
        if goal is None:  # unknown (or long forgotten): status UNKNOWN, as rcl_action answers
            self._answer_result(request, fjt.ActionResult(fjt.STATUS_UNKNOWN, False, {}))
        elif goal.result is None:
            goal.result_requests.append(request)
        else:
            self._answer_result(request, goal.result)

    # --- the line's news of a goal ----------------------------------------------------
    def _accept(self, goal: NativeGoal, status: int = ACCEPTED) -> None:
        if goal.send_request is not None:
            self._answer_send(goal.send_request, True, goal.stamp_s)
            goal.send_request = None
        if goal.result is None and goal.status < status:
            goal.status = status
            self._publish_status()

    def _finished(self, goal: NativeGoal, result: fjt.ActionResult) -> None:
        if not result.accepted:
            self.refused += 1
            if goal.send_request is not None:  # refused before accepted: not accepted, no result to ask for
                self._answer_send(goal.send_request, False, goal.stamp_s)
                self.goals.pop(goal.uuid, None)
                return
            result = fjt.ActionResult(fjt.STATUS_ABORTED, True, result.values)  # refused after ACCEPT_WITHIN_S
        self._accept(goal)
        goal.result, goal.status, goal.finished_at = result, result.status, time.monotonic()
        for request in goal.result_requests:
            self._answer_result(request, result)
        goal.result_requests.clear()
        self._publish_status()

    def _publish_feedback(self, goal: NativeGoal, values: dict) -> None:
        message = {"goal_id": {"uuid": list(goal.uuid)}, "feedback": values}
        self.feedback.put(from_json(f"{self.action_type}_FeedbackMessage", message))

    def _publish_status(self) -> None:
        statuses = [
            {"goal_info": {"goal_id": {"uuid": list(g.uuid)}, "stamp": time_json(g.stamp_s)}, "status": g.status}
            for g in self.goals.values()
            if g.send_request is None
        ]
        self.status.put(from_json("action_msgs/msg/GoalStatusArray", {"status_list": statuses}))

    # --- answers ------------------------------------------------------------------------
    def _answer_send(self, request: Ros2Request, accepted: bool, stamp_s: float) -> None:
        values = {"accepted": accepted, "stamp": time_json(stamp_s)}
        request.reply(from_json(f"{self.action_type}_SendGoal_Response", values))

    def _answer_result(self, request: Ros2Request, result: fjt.ActionResult) -> None:
        values = {"status": result.status, "result": result.values}
        request.reply(from_json(f"{self.action_type}_GetResult_Response", values))

    def close(self) -> None:
        """Goals in flight go on; their clients' pending requests end unanswered with the node."""
        self.goals.clear()
