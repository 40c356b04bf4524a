"""The claw's goals followed: GripperCommand-like goals started, their opening tracked, reached or stalled."""

from __future__ import annotations

import math
from collections.abc import Callable
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


class GripperTracker:
    """One claw's goals: the one running, the one waiting for its start time, the opening and effort commanded.
    An arm's `ArmTracker` holds one and gives it the arm's clock; its results are the claw's own."""

    def __init__(self, opening_of: Callable[[np.ndarray], float], default_effort_n: float = 0.0) -> None:
        self.opening_of = opening_of
        self.default_effort_n = default_effort_n
        self.running: _Gripper | None = None
        self.waiting: _Gripper | None = None  # accepted with a start time still ahead
        self.opening = 1.0
        self.effort_n = default_effort_n

    def submit(self, goal: GripperGoal, now_s: float, estop: bool) -> list[GoalResult]:
        """Accept a claw goal (preempting the claw's others), or refuse it: e-stop, an opening or effort out of
        range, a start time that is not finite."""

        def reject(reason: str) -> list[GoalResult]:
            return [GoalResult(goal.goal_id, "gripper", GoalStatus.REJECTED, ResultCode.INVALID_GOAL, reason, now_s)]

        if estop:
            return reject(ESTOP_REASON)
        if not (math.isfinite(goal.opening) and 0.0 <= goal.opening <= 1.0):
            return reject(f"opening {goal.opening!r} must be within [0, 1]")
        if not (math.isfinite(goal.max_effort_n) and goal.max_effort_n >= 0):
            return reject(f"max effort {goal.max_effort_n!r} must be finite and not negative")
        if goal.start_time_s is not None and not math.isfinite(goal.start_time_s):
            return reject("start time is not finite")
        start = now_s if goal.start_time_s is None else max(goal.start_time_s, now_s)
        reason = f"preempted by goal {goal.goal_id}"
        out = [
            GoalResult(g.goal.goal_id, "gripper", GoalStatus.PREEMPTED, ResultCode.SUCCESSFUL, reason, now_s)
            for g in (self.running, self.waiting)
            if g is not None
        ]
        self.running, self.waiting = None, _Gripper(goal, start)  # the claw keeps its opening until the start
        if start <= now_s:
            self._start()
        return out

    def cancel_waiting(self, now_s: float, reason: str) -> list[GoalResult]:
        """Cancel the claw goal still waiting for its start time (ended ABORTED with `reason`); one already
        started runs on: its opening is commanded, and holding the claw short of it could drop a part."""
        g, self.waiting = self.waiting, None
        if g is None:
            return []
        return [GoalResult(g.goal.goal_id, "gripper", GoalStatus.ABORTED, ResultCode.ABORTED, reason, now_s)]

    def start_if_due(self, now_s: float) -> None:
        """The waiting goal started once its start time has come."""
        if self.waiting is not None and now_s >= self.waiting.start_s - 1e-9:
            self._start()

    def _start(self) -> None:
        self.running, self.waiting = self.waiting, None
        g = self.running.goal
        self.opening = g.opening
        self.effort_n = (
            min(g.max_effort_n, self.default_effort_n)
            if g.max_effort_n > 0 and self.default_effort_n > 0
            else (g.max_effort_n or self.default_effort_n)
        )

    def check(self, now_s: float, gripper_q: np.ndarray, gripper_dq: np.ndarray) -> list[GoalResult]:
        """After the physics stepped: the running goal's result once the claw reached its opening or stalled."""
        g = self.running
        if g is None or now_s < g.start_s:
            return []
        opening = self.opening_of(np.asarray(gripper_q, float))
        speed = abs(self.opening_of(np.asarray(gripper_q, float) + np.asarray(gripper_dq, float)) - opening)
        reached = abs(opening - g.goal.opening) <= GRIPPER_REACHED
        still = speed < GRIPPER_STILL_PER_S
        g.still_since_s = (g.still_since_s if g.still_since_s is not None else now_s) if still else None
        settled = g.still_since_s is not None and now_s - g.still_since_s >= GRIPPER_SETTLE_S
        if not (reached and still) and not settled:
            return []
        self.running = None
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

    def abort(self, now_s: float, reason: str) -> list[GoalResult]:
        """End the running and waiting claw goals ABORTED with `reason`; the claw keeps its opening."""
        out = [
            GoalResult(g.goal.goal_id, "gripper", GoalStatus.ABORTED, ResultCode.ABORTED, reason, now_s)
            for g in (self.running, self.waiting)
            if g is not None
        ]
        self.running = self.waiting = None
        return out

    def goal_ids(self) -> list[int]:
        """The claw goals running or waiting."""
        return [g.goal.goal_id for g in (self.running, self.waiting) if g is not None]

    @property
    def idle(self) -> bool:
        return self.running is None and self.waiting is None
