"""The line's actions for every ROS front end: each `FollowJointTrajectory` or `GripperCommand` goal a client
sent, followed from the sim's results and states to its start, feedback and result, and cancelled as
ros2_controllers' controller does (the arm holds where it is commanded; the goal ends CANCELED). A front end
(rosbridge, rmw_zenoh) says how each goal's news reach its client (`GoalReplies`)."""

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
from robots.spec import RobotSpec

HOLD_S = 0.1  # a cancel: hold where the arm is commanded, reached this fast


@dataclass(frozen=True)
class GoalReplies:
    """How one goal's news reach its client: its result (once), feedback while it drives the arm (None: not
    wanted), and its start (the arm's state first shows it)."""

    result: Callable[[fjt.ActionResult], None]
    feedback: Callable[[dict], None] | None = None
    started: Callable[[], None] | None = None


@dataclass
class PendingGoal:
    owner: object  # the client (a connection, an action server) the goal is cancelled and forgotten by
    op_id: object
    arm: str
    replies: GoalReplies
    started: bool = False


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

    def send(self, owner: object, op_id: object, action: str, goal: object, replies: GoalReplies) -> None:
        """Send a client's goal (JSON-like values) on `action` (one of `names.line_actions`) to its arm; one that
        cannot be read is answered at once (INVALID_GOAL, not accepted)."""
        arm = names.action_arm(action)
        goal_id = self.new_goal_id()
        try:
            if action == names.arm_gripper_action(arm):
                msg = gripper_goal_message(arm, goal_id, goal, self.specs[arm])
            else:
                msg = fjt.trajectory_goal_from_ros(arm, goal_id, goal)
        except ValueError as exc:
            replies.result(fjt.refused(str(exc)))
            return
        self.pending[goal_id] = PendingGoal(owner, op_id, arm, replies)
        self.send_goal(msg)
        self.sent += 1

    def send_trajectory(self, arm: str, trajectory: object) -> None:
        """A fire-and-forget `trajectory_msgs/JointTrajectory` (JSON-like values) to the arm: a goal whose result goes
        to nobody; `GoalError` for one that cannot be read."""
        self.send_goal(fjt.trajectory_goal_from_ros(arm, self.new_goal_id(), {"trajectory": trajectory}))

    def cancel(self, owner: object, op_id: object) -> bool:
        """Cancel the owner's goal `op_id`: the arm holds where it is commanded now (the goal ends CANCELED)."""
        for p in self.pending.values():
            if p.owner is owner and p.op_id == op_id:
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
            p.replies.result(gripper_result(result, position))
        else:
            p.replies.result(fjt.action_result(result))

    def on_state(self, state: ArmState) -> None:
        self.states[state.arm] = state
        p = self.pending.get(state.goal_id)
        if p is None:
            return
        if not p.started:
            p.started = True
            if p.replies.started is not None:
                p.replies.started()
        if p.replies.feedback is not None and state.desired_q:
            p.replies.feedback(fjt.feedback(state, self.arm_joints[state.arm]))

    def arms_in_flight(self) -> set[str]:
        """The arms some client's goal drives or waits on (their states feed its feedback and result)."""
        return {p.arm for p in self.pending.values()}

    def forget(self, owner: object) -> None:
        """A client left: its goals run on, their results go to nobody."""
        for goal_id in [g for g, p in self.pending.items() if p.owner is owner]:
            del self.pending[goal_id]
