"""`control_msgs/action/GripperCommand` over the bus, as ros2_controllers' gripper action controller takes it:
`command.position` is the claw's first joint's position (its own units: metres for a finger slide, radians for a
jaw), mapped onto the sim's opening (0 closed .. 1 open, clamped); the result says where it got, and whether it
reached the goal or stalled on something (a part in the claw)."""

from __future__ import annotations

import math

from fleet.bus.messages import GoalResultMsg, GripperGoalMsg
from fleet.ros.trajectory_action import STATUS_OF, ActionResult, GoalError, refused
from robots.spec import RobotSpec


def gripper_goal_message(arm: str, goal_id: int, goal: object, spec: RobotSpec) -> GripperGoalMsg:
    """A GripperCommand goal as the sim's claw goal; `GoalError` for one that cannot be read."""
    command = goal.get("command") if isinstance(goal, dict) else None
    if not isinstance(command, dict):
        raise GoalError("the goal must have a command {position, max_effort}")
    position, effort = command.get("position"), command.get("max_effort", 0.0)
    for name, value in (("command.position", position), ("command.max_effort", effort)):
        if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
            raise GoalError(f"{name} must be a finite number")
    closed, opened = spec.gripper_closed[0], spec.gripper_open[0]
    opening = min(1.0, max(0.0, (float(position) - closed) / (opened - closed)))
    return GripperGoalMsg(arm, goal_id, opening, max(0.0, float(effort)))


def gripper_result(result: GoalResultMsg, position: float) -> ActionResult:
    """The sim's claw result as GripperCommand's: `position` is where the claw's first joint stands now."""
    values = {"position": position, "effort": 0.0, "stalled": not result.reached, "reached_goal": result.reached}
    if result.status == "rejected":
        return refused(result.reason)
    return ActionResult(STATUS_OF.get(result.status, 6), True, values)


__all__ = ["GoalError", "gripper_goal_message", "gripper_result"]
