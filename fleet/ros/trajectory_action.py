"""`control_msgs/action/FollowJointTrajectory` over the bus: a ROS goal (rosbridge JSON) as the sim's
`TrajectoryGoalMsg`, the sim's `GoalResultMsg` as the action's result and status, its `ArmState` as feedback;
with ros2_controllers' joint trajectory controller's semantics (a preempted goal ends CANCELED, never
SUCCEEDED; error codes are control_msgs')."""

from __future__ import annotations

import math
from dataclasses import dataclass

from fleet.bus.messages import ArmState, GoalResultMsg, TrajectoryGoalMsg
from fleet.ros.ros_json import seconds, time_json

INVALID_GOAL = -1
DEFAULT_GOAL_TIME_TOLERANCE_S = 0.5  # a goal's 0 means "the controller's default", as in ros2_controllers
# action_msgs/msg/GoalStatus
STATUS_UNKNOWN, STATUS_SUCCEEDED, STATUS_CANCELED, STATUS_ABORTED = 0, 4, 5, 6
STATUS_OF = {"succeeded": STATUS_SUCCEEDED, "aborted": STATUS_ABORTED, "preempted": STATUS_CANCELED}


class GoalError(ValueError):
    """A goal that cannot be read (the message names the field); refused with INVALID_GOAL."""


@dataclass(frozen=True)
class ActionResult:
    """What the action's client gets: the goal's status, whether it was accepted at all, and the result fields."""

    status: int
    accepted: bool
    values: dict


def _floats(value: object, field: str) -> tuple[float, ...]:
    if not isinstance(value, list) or not all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value
    ):
        raise GoalError(f"{field} must be a list of finite numbers")
    return tuple(float(v) for v in value)


def _rows(points: list[dict], field: str, n: int) -> tuple[float, ...]:
    """The points' `field` flattened, or () when every point leaves it empty; all or none must give it."""
    rows = [_floats(p.get(field, []), f"points[{i}].{field}") for i, p in enumerate(points)]
    if not any(rows):
        return ()
    if any(len(r) != n for r in rows):
        raise GoalError(f"every point's {field} must have one value per joint ({n}) or none")
    return tuple(v for r in rows for v in r)


def _tolerances(items: object, joints: list[str], field: str) -> tuple[float, ...]:
    """Position tolerances (`control_msgs/JointTolerance`) by joint, in `joints` order; () when none is set."""
    if not isinstance(items, list):
        raise GoalError(f"{field} must be a list of JointTolerance")
    by_name = {}
    for i, item in enumerate(items):
        if not isinstance(item, dict) or not isinstance(item.get("name"), str):
            raise GoalError(f"{field}[{i}] must be a JointTolerance with a name")
        by_name[item["name"]] = _floats([item.get("position", 0.0)], f"{field}[{i}].position")[0]
    values = tuple(max(0.0, by_name.get(j, 0.0)) for j in joints)
    return values if any(values) else ()


def trajectory_goal_from_ros(arm: str, goal_id: int, goal: object) -> TrajectoryGoalMsg:
    """A `FollowJointTrajectory` goal as the sim's trajectory goal; `GoalError` for one that cannot be read (the
    sim itself refuses what is readable but wrong: unknown joints, times that do not increase, unsafe paths)."""
    if not isinstance(goal, dict) or not isinstance(goal.get("trajectory"), dict):
        raise GoalError("the goal must have a trajectory")
    trajectory = goal["trajectory"]
    joints = trajectory.get("joint_names")
    if not isinstance(joints, list) or not joints or not all(isinstance(j, str) for j in joints):
        raise GoalError("trajectory.joint_names must be a non-empty list of names")
    joints = [j.removeprefix(f"{arm}/") for j in joints]  # `/joint_states`' names (`<arm>/<joint>`) are taken too
    points = trajectory.get("points")
    if not isinstance(points, list) or not points or not all(isinstance(p, dict) for p in points):
        raise GoalError("trajectory.points must be a non-empty list of JointTrajectoryPoint")
    positions = _rows(points, "positions", len(joints))
    if not positions:
        raise GoalError("every point needs positions")
    times = tuple(seconds(p.get("time_from_start", {}), f"points[{i}].time_from_start") for i, p in enumerate(points))
    stamp = seconds(trajectory.get("header", {}).get("stamp", {}), "trajectory.header.stamp")
    tolerance = seconds(goal.get("goal_time_tolerance", {}), "goal_time_tolerance")
    return TrajectoryGoalMsg(
        arm,
        goal_id,
        tuple(joints),
        times,
        positions,
        _rows(points, "velocities", len(joints)),
        _rows(points, "accelerations", len(joints)),
        stamp if stamp > 0 else None,  # a zero stamp: now, as the controller takes it
        _tolerances(goal.get("path_tolerance", []), joints, "path_tolerance"),
        _tolerances(goal.get("goal_tolerance", []), joints, "goal_tolerance"),
        tolerance if tolerance > 0 else DEFAULT_GOAL_TIME_TOLERANCE_S,
    )


def action_result(result: GoalResultMsg) -> ActionResult:
    """The sim's result as the action's: a refused goal is not accepted (its code and reason say why)."""
    values = {"error_code": result.code, "error_string": result.reason}
    if result.status == "rejected":
        return ActionResult(STATUS_UNKNOWN, False, values)
    return ActionResult(STATUS_OF.get(result.status, STATUS_ABORTED), True, values)


def refused(reason: str) -> ActionResult:
    return ActionResult(STATUS_UNKNOWN, False, {"error_code": INVALID_GOAL, "error_string": reason})


def feedback(state: ArmState, joint_names: list[str]) -> dict:
    """`FollowJointTrajectory_Feedback` from the arm's state while this goal drives it: desired, actual, error."""

    def point(q, dq) -> dict:
        return {"positions": list(q), "velocities": list(dq), "accelerations": [], "effort": [],
                "time_from_start": time_json(0.0)}  # fmt: skip

    error = [d - a for d, a in zip(state.desired_q, state.q)]
    derror = [d - a for d, a in zip(state.desired_dq, state.dq)]
    return {
        "header": {"stamp": time_json(state.sim_time_s), "frame_id": ""},
        "joint_names": joint_names,
        "desired": point(state.desired_q, state.desired_dq),
        "actual": point(state.q, state.dq),
        "error": point(error, derror),
    }
