"""The cerebellum: one arm's trajectory tracker, as an arm's firmware (or ROS's joint_trajectory_controller) holds it.

It follows the active trajectory goal at the servo rate, splices a newer goal in at
that goal's start time (the old one is preempted), holds the last point when a
trajectory ends, checks path and goal tolerances, clamps to the joint limits, and
stops on e-stop or when the controller's watchdog deadline passes: every active goal
is aborted with its reason and the arm holds where it is. The gripper takes
GripperCommand-like goals beside it. Pure computation: the sim server (or any driver)
reads `desired()` / `gripper_opening()` each tick and reports the joints to `update()`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from robots.gripper_tracking import GripperTracker
from robots.joint_trajectory import (
    ESTOP_ABORT_REASON,
    ESTOP_REASON,
    ArmGoal,
    CheckedGoal,
    GoalResult,
    GoalStatus,
    GripperGoal,
    ResultCode,
    Spline,
    TrajectoryGoal,
    check_goal,
)

WATCHDOG_REASON = "watchdog: the controller missed its deadline"


@dataclass
class _Active:
    checked: CheckedGoal
    spline: Spline
    # its result is out (preempted by a goal that starts later): it drives the arm, unchecked, until then
    ended: bool = False


@dataclass(frozen=True)
class PlannedGoal:
    """A trajectory goal checked and splined against the arm's path, not yet committed (`ArmTracker.commit`)."""

    active: _Active

    @property
    def spline(self) -> Spline:
        return self.active.spline


def mean_opening(gripper_q: np.ndarray) -> float:
    """A gripper's opening read as the mean of its joints (a gripper whose joints run 0 closed to 1 open)."""
    return float(np.mean(gripper_q))


class ArmTracker:
    """One arm: joint names and limits in the arm's order; its claw's goals in `claw`, the opening read through
    `opening_of`."""

    def __init__(
        self,
        joint_names: tuple[str, ...],
        lower: np.ndarray,
        upper: np.ndarray,
        hold_q: np.ndarray,
        *,
        opening_of=None,
        default_effort_n: float = 0.0,
        servo_period_s: float | None = None,
    ) -> None:
        self.joint_names = tuple(joint_names)
        self.servo_period_s = servo_period_s  # ticks at multiples of it read the trajectory from a grid built once
        self.lower, self.upper = np.asarray(lower, float), np.asarray(upper, float)
        self.hold_q = np.asarray(hold_q, float).copy()
        self.claw = GripperTracker(opening_of or mean_opening, default_effort_n)
        self.active: _Active | None = None
        self.next: _Active | None = None  # accepted with a start time still ahead: the current path runs until then
        self.estop = False
        self.watchdog_deadline_s = math.inf
        self.clamped = 0
        self.last: GoalResult | None = None  # the newest trajectory result, echoed in the arm's state
        # the last targets
        self.desired_now: tuple[np.ndarray, np.ndarray] = (self.hold_q.copy(), np.zeros_like(self.hold_q))

    # --- goals in -------------------------------------------------------------------
    def submit(self, goal: ArmGoal, now_s: float) -> list[GoalResult]:
        """Accept or refuse a goal at `now_s`; returns the refusal, or the results of the goals it preempts."""
        if isinstance(goal, GripperGoal):
            return self.claw.submit(goal, now_s, self.estop)
        planned = self.plan(goal, now_s)
        return planned if isinstance(planned, list) else self.commit(planned, now_s)

    def plan(self, goal: TrajectoryGoal, now_s: float) -> PlannedGoal | list[GoalResult]:
        """The path a trajectory goal would give the arm from its start on, or its refusal (e-stop, invalid goal);
        nothing changes until `commit`, so a safety layer can look at the path first."""
        if self.estop:
            return self.refuse(goal, ESTOP_REASON, now_s)
        checked = check_goal(goal, self.joint_names, self.lower, self.upper)
        if isinstance(checked, GoalResult):
            return self._note([dataclasses.replace(checked, time_s=now_s)])
        start = now_s if goal.start_time_s is None else max(goal.start_time_s, now_s)
        # it replaces a pending goal (which then never runs): it starts from the path that runs until then
        q0, dq0, ddq0 = self._path_at(start, with_pending=False)
        return PlannedGoal(_Active(checked, Spline.through(start, q0, dq0, ddq0, checked, self.servo_period_s)))

    def refuse(
        self, goal: TrajectoryGoal, reason: str, now_s: float, code: ResultCode = ResultCode.INVALID_GOAL
    ) -> list[GoalResult]:
        """Refuse a trajectory goal with `reason`: it never starts, the arm keeps its path."""
        return self._note([GoalResult(goal.goal_id, "trajectory", GoalStatus.REJECTED, code, reason, now_s)])

    def commit(self, planned: PlannedGoal, now_s: float) -> list[GoalResult]:
        """Make a planned goal the arm's path from its start; returns the results of the goals it preempts."""
        new, goal_id = planned.active, planned.active.checked.goal.goal_id
        start = new.spline.t0_s
        out = [
            self._end(
                old, "trajectory", GoalStatus.PREEMPTED, ResultCode.SUCCESSFUL, f"preempted by goal {goal_id}", now_s
            )
            for old in (self.active, self.next)
            if old is not None and not old.ended
        ]
        if start <= now_s:
            self.active, self.next = new, None
        else:
            self.next = new  # the current path (or the hold) runs until the new goal's start
            if self.active is not None:
                self.active.ended = True
        return self._note(out)

    def committed_end_s(self) -> float:
        """When the arm's committed path comes to rest (-inf when it holds already): a goal that holds its last
        point rests from there, although it runs on."""
        ends = [a.spline.moves_until_s for a in (self.active, self.next) if a is not None]
        return max(ends, default=-math.inf)

    def path_q(self, t_s: float) -> np.ndarray:
        """Where the arm's committed path puts its joints at `t_s` (now or later)."""
        if self.next is not None and t_s >= self.next.spline.t0_s:
            return self.next.spline.q_at(t_s)
        return self.active.spline.q_at(t_s) if self.active is not None else self.hold_q

    # --- each tick ------------------------------------------------------------------
    def _path_at(self, t_s: float, with_pending: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where the commanded path is at `t_s` (a pending goal from its start on, unless not `with_pending`; the
        hold point if none)."""
        if with_pending and self.next is not None and t_s >= self.next.spline.t0_s:
            return self.next.spline.sample(t_s)
        if self.active is not None:
            return self.active.spline.sample(t_s)
        zero = np.zeros_like(self.hold_q)
        return self.hold_q.copy(), zero, zero

    def desired(self, now_s: float) -> tuple[np.ndarray, np.ndarray]:
        """The joint position and velocity targets for now (clamped to the limits; clamps are counted)."""
        if self.next is not None and now_s >= self.next.spline.t0_s - 1e-9:
            self.active, self.next = self.next, None
        self.claw.start_if_due(now_s)
        if self.active is None and self.next is None:  # holding: the same targets as last time
            if self.desired_now[0] is not self.hold_q:
                self.desired_now = (self.hold_q, np.zeros_like(self.hold_q))
            return self.desired_now
        a = self.next if self.next is not None and now_s >= self.next.spline.t0_s else self.active
        q, dq = a.spline.state(now_s) if a is not None else (self.hold_q, np.zeros_like(self.hold_q))
        clamped = np.clip(q, self.lower, self.upper)
        if np.any(clamped != q):
            self.clamped += 1
        self.desired_now = (clamped, dq)
        return clamped, dq

    def update(self, now_s: float, q: np.ndarray, gripper_q: np.ndarray, gripper_dq: np.ndarray) -> list[GoalResult]:
        """After the physics stepped to `now_s`: tolerances, ends of goals, the watchdog. Returns the results."""
        if now_s > self.watchdog_deadline_s:
            return self.abort(now_s, q, WATCHDOG_REASON)
        out = []
        a = self.active
        if a is not None and not a.ended:
            out += self._check(a, now_s, np.asarray(q, float))
        return self._note(out) + self.claw.check(now_s, gripper_q, gripper_dq)

    def _check(self, a: _Active, now_s: float, q: np.ndarray) -> list[GoalResult]:
        goal, spline = a.checked.goal, a.spline
        if now_s < spline.t_end_s:
            want, _ = spline.state(now_s)
            over = np.abs(want - q) > a.checked.path_tolerance
            if over.any():
                j = int(np.argmax(over))
                return self.abort(
                    now_s,
                    q,
                    f"{self.joint_names[j]} {abs(want[j] - q[j]):.3f} rad off its path",
                    ResultCode.PATH_TOLERANCE_VIOLATED,
                )
            return []
        err = np.abs(q - spline.q_end)
        if np.all(err <= a.checked.goal_tolerance):
            self.hold_q, self.active = spline.q_end.copy(), None
            return [GoalResult(goal.goal_id, "trajectory", GoalStatus.SUCCEEDED, ResultCode.SUCCESSFUL, "", now_s)]
        if now_s > spline.t_end_s + goal.goal_time_tolerance_s:
            j = int(np.argmax(err - np.where(np.isfinite(a.checked.goal_tolerance), a.checked.goal_tolerance, 0)))
            self.hold_q, self.active = spline.q_end.copy(), None
            return [
                GoalResult(
                    goal.goal_id,
                    "trajectory",
                    GoalStatus.ABORTED,
                    ResultCode.GOAL_TOLERANCE_VIOLATED,
                    f"{self.joint_names[j]} {err[j]:.3f} rad from its goal {goal.goal_time_tolerance_s:g} s after the "
                    "end",
                    now_s,
                )
            ]
        return []

    # --- safety ---------------------------------------------------------------------
    def abort(
        self, now_s: float, q: np.ndarray, reason: str, code: ResultCode = ResultCode.ABORTED
    ) -> list[GoalResult]:
        """Abort every active or pending goal (arm and gripper) and hold the arm where it is now."""
        out = self.stop_path(now_s, q, reason, code)
        if code == ResultCode.ABORTED:
            out += self.claw.abort(now_s, reason)
        self.watchdog_deadline_s = math.inf
        return out

    def stop_path(
        self, now_s: float, q: np.ndarray, reason: str, code: ResultCode = ResultCode.ABORTED
    ) -> list[GoalResult]:
        """End the trajectory goals (running and waiting) with `reason` and hold the arm where it is; the claw's
        goals go on (an outside client took the arm with a claw goal; `abort` ends them too)."""
        out = [
            self._end(x, "trajectory", GoalStatus.ABORTED, code, reason, now_s)
            for x in (self.active, self.next)
            if x is not None and not x.ended
        ]
        self.active = self.next = None
        self.hold_q = np.clip(np.asarray(q, float), self.lower, self.upper)
        return self._note(out)

    def set_estop(self, engaged: bool, now_s: float, q: np.ndarray) -> list[GoalResult]:
        """Engage (abort everything, hold, refuse goals) or release (hold still until a new goal)."""
        self.estop = engaged
        return self.abort(now_s, q, ESTOP_ABORT_REASON) if engaged else []

    def watch(self, deadline_s: float) -> None:
        """The controller must be heard from again before `deadline_s` (sim time), or the arm stops."""
        self.watchdog_deadline_s = deadline_s

    def unwatch(self) -> None:
        self.watchdog_deadline_s = math.inf

    @property
    def idle(self) -> bool:
        """No goal running or waiting to start: the arm holds and nothing needs checking but the watchdog."""
        return self.active is None and self.next is None and self.claw.idle

    def gripper_opening(self) -> float:
        """The claw's commanded opening now."""
        return self.claw.opening

    @property
    def goal_id(self) -> int:
        """The trajectory goal driving the arm now or about to (0: none, the arm holds)."""
        a = self.next or self.active
        return a.checked.goal.goal_id if a is not None else 0

    def _end(
        self, a: _Active, kind: str, status: GoalStatus, code: ResultCode, reason: str, now_s: float
    ) -> GoalResult:
        return GoalResult(a.checked.goal.goal_id, kind, status, code, reason, now_s)

    def _note(self, results: list[GoalResult]) -> list[GoalResult]:
        for r in results:
            if r.kind == "trajectory":
                self.last = r
        return results
