"""The claw's goals followed: GripperCommand-like goals started, their opening tracked, reached or stalled."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from robots.joint_trajectory import (
    ESTOP_REASON,
    GoalResult,
    GoalStatus,
    GripperGoal,
    ResultCode,
)

GRIPPER_REACHED = 0.03  # opening units: within this of the target the claw has reached it
GRIPPER_STILL_PER_S = 0.05  # opening units per second: slower than this the claw has stopped
GRIPPER_SETTLE_S = 0.1  # the claw must stay stopped this long to count as stalled


@dataclass
class _Gripper:
    goal: GripperGoal
    start_s: float
    still_since_s: float | None = None


class GripperTracking:
    """Following claw goals: one concern of `ArmTracker`, kept apart (it shares the tracker's clock and results)."""

    def _submit_gripper(self, goal: GripperGoal, now_s: float) -> list[GoalResult]:
        def reject(reason: str) -> list[GoalResult]:
            return self._note(
                [GoalResult(goal.goal_id, "gripper", GoalStatus.REJECTED, ResultCode.INVALID_GOAL, reason, now_s)]
            )

        if self.estop:
            return reject(ESTOP_REASON)
        if not (math.isfinite(goal.opening) and 0.0 <= goal.opening <= 1.0):
            return reject(f"opening {goal.opening!r} must be within [0, 1]")
        if not (math.isfinite(goal.max_effort_n) and goal.max_effort_n >= 0):
            return reject(f"max effort {goal.max_effort_n!r} must be finite and not negative")
        if goal.start_time_s is not None and not math.isfinite(goal.start_time_s):
            return reject("start time is not finite")
        start = now_s if goal.start_time_s is None else max(goal.start_time_s, now_s)
        out = [
            GoalResult(
                g.goal.goal_id,
                "gripper",
                GoalStatus.PREEMPTED,
                ResultCode.SUCCESSFUL,
                f"preempted by goal {goal.goal_id}",
                now_s,
            )
            for g in (self.gripper, self.next_gripper)
            if g is not None
        ]
        self.gripper, self.next_gripper = None, _Gripper(goal, start)  # the claw keeps its opening until the start
        if start <= now_s:
            self._start_gripper()
        return self._note(out)

    def cancel_waiting_gripper(self, now_s: float, reason: str) -> list[GoalResult]:
        """Cancel the claw goal still waiting for its start time (ended ABORTED with `reason`); one already
        started runs on: its opening is commanded, and holding the claw short of it could drop a part."""
        g, self.next_gripper = self.next_gripper, None
        if g is None:
            return []
        return [GoalResult(g.goal.goal_id, "gripper", GoalStatus.ABORTED, ResultCode.ABORTED, reason, now_s)]

    def _start_gripper(self) -> None:
        self.gripper, self.next_gripper = self.next_gripper, None
        g = self.gripper.goal
        self.opening = g.opening
        self.effort_n = (
            min(g.max_effort_n, self.default_effort_n)
            if g.max_effort_n > 0 and self.default_effort_n > 0
            else (g.max_effort_n or self.default_effort_n)
        )

    def gripper_opening(self) -> float:
        return self.opening

    def _check_gripper(
        self, g: _Gripper, now_s: float, gripper_q: np.ndarray, gripper_dq: np.ndarray
    ) -> list[GoalResult]:
        opening = self.opening_of(np.asarray(gripper_q, float))
        speed = abs(self.opening_of(np.asarray(gripper_q, float) + np.asarray(gripper_dq, float)) - opening)
        reached = abs(opening - g.goal.opening) <= GRIPPER_REACHED
        still = speed < GRIPPER_STILL_PER_S
        g.still_since_s = (g.still_since_s if g.still_since_s is not None else now_s) if still else None
        settled = g.still_since_s is not None and now_s - g.still_since_s >= GRIPPER_SETTLE_S
        if not (reached and still) and not settled:
            return []
        self.gripper = None
        return [
            GoalResult(
                g.goal.goal_id,
                "gripper",
                GoalStatus.SUCCEEDED,
                ResultCode.SUCCESSFUL,
                "" if reached else f"stalled at opening {opening:.3f}",
                now_s,
                reached=reached,
                stalled=not reached,
            )
        ]
