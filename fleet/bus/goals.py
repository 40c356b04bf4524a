"""Trajectory and gripper goals and their results between the bus messages and `robots.joint_trajectory`.

Goals travel flat (one row of joint values per point, rows end to end); a goal whose rows
do not divide into its points is refused with its reason, like any other invalid goal.
"""

from __future__ import annotations

from fleet.bus.messages import ArmGoalMsg, GoalResultMsg, GripperGoalMsg, TrajectoryGoalMsg
from robots.joint_trajectory import ArmGoal, GoalResult, GoalStatus, GripperGoal, ResultCode, TrajectoryGoal


def goal_message(arm: str, goal: ArmGoal) -> ArmGoalMsg:
    """The bus form of a goal for `arm`."""
    if isinstance(goal, GripperGoal):
        return GripperGoalMsg(arm, goal.goal_id, goal.opening, goal.max_effort_n, goal.start_time_s)
    flat = lambda rows: tuple(float(v) for row in rows for v in row)  # noqa: E731
    return TrajectoryGoalMsg(
        arm,
        goal.goal_id,
        tuple(goal.joint_names),
        tuple(map(float, goal.times_from_start_s)),
        flat(goal.positions),
        flat(goal.velocities),
        flat(goal.accelerations),
        goal.start_time_s,
        tuple(goal.path_tolerance_rad),
        tuple(goal.goal_tolerance_rad),
        goal.goal_time_tolerance_s,
    )


def goal_from_message(msg: ArmGoalMsg) -> ArmGoal | GoalResult:
    """The goal a message carries, or its refusal (INVALID_GOAL with the reason) when its rows do not fit."""
    if isinstance(msg, GripperGoalMsg):
        return GripperGoal(msg.goal_id, msg.opening, msg.max_effort_n, msg.start_time_s)
    n, points = len(msg.joint_names), len(msg.times_from_start_s)

    def rows(values: tuple[float, ...], what: str, optional: bool) -> tuple[tuple[float, ...], ...] | str:
        if optional and not values:
            return ()
        if n == 0 or len(values) != n * points:
            return f"{what}: {len(values)} values for {points} points of {n} joints"
        return tuple(tuple(values[i * n : (i + 1) * n]) for i in range(points))

    fields = {}
    for what, values, optional in (
        ("positions", msg.positions, False),
        ("velocities", msg.velocities, True),
        ("accelerations", msg.accelerations, True),
    ):
        out = rows(values, what, optional)
        if isinstance(out, str):
            return GoalResult(msg.goal_id, "trajectory", GoalStatus.REJECTED, ResultCode.INVALID_GOAL, out)
        fields[what] = out
    return TrajectoryGoal(
        msg.goal_id,
        tuple(msg.joint_names),
        tuple(msg.times_from_start_s),
        fields["positions"],
        fields["velocities"],
        fields["accelerations"],
        msg.start_time_s,
        tuple(msg.path_tolerance_rad),
        tuple(msg.goal_tolerance_rad),
        msg.goal_time_tolerance_s,
    )


def result_message(arm: str, r: GoalResult) -> GoalResultMsg:
    return GoalResultMsg(
        arm, r.goal_id, r.kind, r.status.value, int(r.code), r.reason, float(r.time_s), r.reached, r.stalled
    )
