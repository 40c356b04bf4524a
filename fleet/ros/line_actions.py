"""The line's actions for rosbridge clients: each `FollowJointTrajectory` goal a client sent, followed from the
sim's results and states to its feedback and result, and cancelled as ros2_controllers' controller does (the arm
holds where it is commanded; the goal ends CANCELED)."""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Callable
from dataclasses import dataclass

from fleet.bus.messages import ArmGoalMsg, ArmState, GoalResultMsg, TrajectoryGoalMsg
from fleet.ros import names
from fleet.ros import trajectory_action as fjt
from fleet.ros.gripper_action import gripper_goal_message, gripper_result
from fleet.ros.ros_json import to_json
from fleet.ros.rosbridge_client import Client
from robots.spec import RobotSpec

HOLD_S = 0.1  # a cancel: hold where the arm is commanded, reached this fast


@dataclass
class PendingGoal:
    client: Client
    op_id: object
    action: str
    arm: str
    joint_names: list[str]
    feedback: bool


class LineActions:
    """Goals in flight from rosbridge clients, by the goal id the sim knows them by."""

    def __init__(self, specs: dict[str, RobotSpec], send_goal: Callable[[ArmGoalMsg], None]) -> None:
        self.specs = specs
        self.arm_joints = {arm: list(spec.arm_joints) for arm, spec in specs.items()}  # as the states give them
        self.send_goal = send_goal
        # ids no other client's goals use: far above the controllers' (incarnation << 20), one range per process
        base = (1 << 52) + (int.from_bytes(os.urandom(2), "little") << 32)
        self._ids = itertools.count(base)
        self.pending: dict[int, PendingGoal] = {}
        self.states: dict[str, ArmState] = {}
        self.sent = 0

    def new_goal_id(self) -> int:
        return next(self._ids)

    def send(self, client: Client, op_id: object, action: str, arm: str, goal: object, feedback: bool) -> None:
        """Send a client's goal (`action` of `names.line_actions`) to the arm; one that cannot be read is answered
        at once (INVALID_GOAL)."""
        goal_id = self.new_goal_id()
        try:
            if action == names.arm_gripper_action(arm):
                msg = gripper_goal_message(arm, goal_id, goal, self.specs[arm])
            else:
                msg = fjt.goal_message(arm, goal_id, goal)
        except ValueError as exc:
            self._answer(PendingGoal(client, op_id, action, arm, [], False), fjt.refused(str(exc)))
            return
        self.pending[goal_id] = PendingGoal(client, op_id, action, arm, list(getattr(msg, "joint_names", ())), feedback)
        self.send_goal(msg)
        self.sent += 1

    def cancel(self, client: Client, op_id: object) -> bool:
        """Cancel the client's goal `op_id`: the arm holds where it is commanded now (the goal ends CANCELED)."""
        for p in self.pending.values():
            if p.client is client and p.op_id == op_id:
                state = self.states.get(p.arm)
                if state is None:
                    return False
                hold = self.new_goal_id()  # a goal of nobody's: its result goes to no client
                q = state.desired_q or state.q
                self.send_goal(TrajectoryGoalMsg(p.arm, hold, tuple(self.arm_joints[p.arm]), (HOLD_S,), tuple(q)))
                return True
        return False

    def on_result(self, result: GoalResultMsg) -> None:
        p = self.pending.pop(result.goal_id, None)
        if p is None:
            return
        if result.kind == "gripper":
            state = self.states.get(p.arm)
            position = float(state.gripper_q[0]) if state is not None and state.gripper_q else math.nan
            self._answer(p, gripper_result(result, position))
        else:
            self._answer(p, fjt.action_result(result))

    def on_state(self, state: ArmState) -> None:
        self.states[state.arm] = state
        p = self.pending.get(state.goal_id)
        if p is not None and p.feedback and state.desired_q:
            feedback = fjt.feedback(state, self.arm_joints[state.arm])
            p.client.send({"op": "action_feedback", "id": p.op_id, "action": p.action, "values": feedback})

    def forget(self, client: Client) -> None:
        """A client left: its goals run on, their results go to nobody."""
        for goal_id in [g for g, p in self.pending.items() if p.client is client]:
            del self.pending[goal_id]

    @staticmethod
    def _answer(p: PendingGoal, result: fjt.ActionResult) -> None:
        out = {"op": "action_result", "action": p.action, "values": result.values, "status": result.status,
               "result": result.accepted}  # fmt: skip
        if p.op_id is not None:
            out["id"] = p.op_id
        p.client.send(to_json(out))
