"""Joint trajectory goals with FollowJointTrajectory semantics: the goal, its validation and its spline.

A goal names the arm's joints, gives points (positions; velocities and accelerations
optional, all points alike) at increasing `time_from_start`, a start time in sim
seconds (None: now) and tolerances. Between points the spline is linear (positions
only), cubic (with velocities) or quintic (with accelerations), as ROS's
joint_trajectory_controller interpolates; `scipy.interpolate.BPoly.from_derivatives`
builds it. Result codes are control_msgs/FollowJointTrajectory's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum, IntEnum
from functools import cached_property

import numpy as np
from scipy.interpolate import BPoly

# a goal moves for at most this long (s): its spline is sampled at every servo tick while it moves, and checked by
# the plant's safety layer over that time, so the cost of a goal grows with it. Holding its last point costs
# nothing, and may last as long as the goal says.
MAX_MOVING_S = 600.0
LIMIT_SLACK_RAD = 1e-5  # limits pass through float32 in the simulator: a point exactly at a limit must not be refused


class ResultCode(IntEnum):
    """control_msgs/FollowJointTrajectory result codes (GripperCommand goals reuse SUCCESSFUL and INVALID_GOAL)."""

    SUCCESSFUL = 0
    INVALID_GOAL = -1
    INVALID_JOINTS = -2
    OLD_HEADER_TIMESTAMP = -3
    PATH_TOLERANCE_VIOLATED = -4
    GOAL_TOLERANCE_VIOLATED = -5
    ABORTED = -6  # clawfleet's: a safety stop (e-stop, watchdog, lost controller); control_msgs has no code for it


ESTOP_REASON = "emergency stop engaged"  # a goal refused while the e-stop holds the arm
ESTOP_ABORT_REASON = "emergency stop"  # the goals the e-stop aborted


OUTSIDE_REASON = "driven from outside"  # a goal refused or preempted because an outside client drives the arm


def stopped_by_hold(reason: str) -> bool:
    """Whether a goal's result reason says a hold ended it (refused or aborted): the e-stop, or an outside client
    that took the arm. Not the goal's own fault."""
    return reason.startswith((ESTOP_ABORT_REASON, OUTSIDE_REASON))


class GoalStatus(str, Enum):
    """How a goal ended (actionlib's terminal states): or `active` while it runs."""

    ACTIVE = "active"
    SUCCEEDED = "succeeded"
    ABORTED = "aborted"  # path or goal tolerance, e-stop, watchdog
    REJECTED = "rejected"  # invalid goal: never started, the arm holds
    PREEMPTED = "preempted"  # replaced by a newer goal


@dataclass(frozen=True)
class TrajectoryGoal:
    """Follow `positions[i]` at `times_from_start_s[i]` after `start_time_s` (None: when received).

    `velocities` / `accelerations` are empty or one row per point. Tolerances (rad) are empty
    (not checked), one value for every joint, or one per joint; `goal_time_tolerance_s` is how
    long after the last point the joints may take to come within the goal tolerance.
    """

    goal_id: int
    joint_names: tuple[str, ...]
    times_from_start_s: tuple[float, ...]
    positions: tuple[tuple[float, ...], ...]
    velocities: tuple[tuple[float, ...], ...] = ()
    accelerations: tuple[tuple[float, ...], ...] = ()
    start_time_s: float | None = None
    path_tolerance_rad: tuple[float, ...] = ()
    goal_tolerance_rad: tuple[float, ...] = ()
    goal_time_tolerance_s: float = 0.5


@dataclass(frozen=True)
class GripperGoal:
    """GripperCommand-like: drive the claw to `opening` (0 closed, 1 open) with at most `max_effort_n` (0: the
    robot's own limit), from `start_time_s` (None: when received). Ends reached, or stalled on something held."""

    goal_id: int
    opening: float
    max_effort_n: float = 0.0
    start_time_s: float | None = None


ArmGoal = TrajectoryGoal | GripperGoal


@dataclass(frozen=True)
class GoalResult:
    """The one result of a goal: its status, control_msgs code and a reason for anything but success.
    Gripper results also say whether the claw `reached` its opening or `stalled` on a part."""

    goal_id: int
    kind: str  # "trajectory" or "gripper"
    status: GoalStatus
    code: ResultCode
    reason: str = ""
    time_s: float = 0.0
    reached: bool = False
    stalled: bool = False


def _per_joint(values: tuple[float, ...], n: int, what: str) -> np.ndarray | str:
    if len(values) == 0:
        return np.full(n, np.inf)
    if len(values) not in (1, n):
        return f"{what} has {len(values)} values: give none, one, or one per joint ({n})"
    arr = np.asarray(values, float)
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        return f"{what} must be finite and not negative"
    arr = np.where(arr == 0, np.inf, arr)  # 0 = not checked, as in control_msgs
    return np.broadcast_to(arr, (n,)).copy()


@dataclass(frozen=True)
class CheckedGoal:
    """A goal that passed validation, with its arrays in the arm's joint order."""

    goal: TrajectoryGoal
    times_s: np.ndarray
    positions: np.ndarray  # (points, joints)
    velocities: np.ndarray | None
    accelerations: np.ndarray | None
    path_tolerance: np.ndarray
    goal_tolerance: np.ndarray


def check_goal(
    goal: TrajectoryGoal, joint_names: tuple[str, ...], lower: np.ndarray, upper: np.ndarray
) -> CheckedGoal | GoalResult:
    """The goal in the arm's joint order, or a rejection naming what is wrong (INVALID_JOINTS or INVALID_GOAL)."""

    def reject(code: ResultCode, reason: str) -> GoalResult:
        return GoalResult(goal.goal_id, "trajectory", GoalStatus.REJECTED, code, reason)

    n = len(joint_names)
    names = tuple(goal.joint_names)
    unknown = [j for j in names if j not in joint_names]
    if unknown or len(set(names)) != len(names) or len(names) != n:
        why = f"unknown joint names {unknown}" if unknown else f"{len(names)} names given ({len(set(names))} distinct)"
        return reject(ResultCode.INVALID_JOINTS, f"{why}; this arm's joints are {', '.join(joint_names)}")
    order = [names.index(j) for j in joint_names]
    if not goal.positions:
        return reject(ResultCode.INVALID_GOAL, "the trajectory has no points")
    if len(goal.times_from_start_s) != len(goal.positions):
        return reject(ResultCode.INVALID_GOAL, f"{len(goal.positions)} points but {len(goal.times_from_start_s)} times")
    arrays = {}
    for what, rows in (
        ("positions", goal.positions),
        ("velocities", goal.velocities),
        ("accelerations", goal.accelerations),
    ):
        if what != "positions" and len(rows) == 0:
            arrays[what] = None
            continue
        if len(rows) != len(goal.positions) or any(len(r) != n for r in rows):
            return reject(ResultCode.INVALID_GOAL, f"{what}: every point needs {n} values (one per joint)")
        arr = np.asarray(rows, float)
        if not np.all(np.isfinite(arr)):
            return reject(ResultCode.INVALID_GOAL, f"{what} contain NaN or infinity")
        arrays[what] = arr[:, order]
    if arrays["accelerations"] is not None and arrays["velocities"] is None:
        return reject(ResultCode.INVALID_GOAL, "accelerations need velocities too")
    times = np.asarray(goal.times_from_start_s, float)
    if why := _times_problem(goal, times, arrays):
        return reject(ResultCode.INVALID_GOAL, why)
    pos = arrays["positions"]
    beyond = np.nonzero(np.any((pos < lower - LIMIT_SLACK_RAD) | (pos > upper + LIMIT_SLACK_RAD), axis=0))[0]
    if beyond.size:
        j = int(beyond[0])
        return reject(
            ResultCode.INVALID_GOAL, f"positions beyond the limits of {joint_names[j]} [{lower[j]:.4g}, {upper[j]:.4g}]"
        )
    path = _per_joint(goal.path_tolerance_rad, n, "path tolerance")
    end = _per_joint(goal.goal_tolerance_rad, n, "goal tolerance")
    for tol in (path, end):
        if isinstance(tol, str):
            return reject(ResultCode.INVALID_GOAL, tol)
    if not (math.isfinite(goal.goal_time_tolerance_s) and goal.goal_time_tolerance_s >= 0):
        return reject(ResultCode.INVALID_GOAL, "goal time tolerance must be finite and not negative")
    return CheckedGoal(goal, times, pos, arrays["velocities"], arrays["accelerations"], path, end)


def _times_problem(goal: TrajectoryGoal, times: np.ndarray, arrays: dict[str, np.ndarray | None]) -> str:
    """What is wrong with a goal's times ("" if nothing): their order, its start, how long it moves."""
    if not np.all(np.isfinite(times)) or times[0] < 0 or np.any(np.diff(times) <= 0):
        return "times_from_start must be finite, not negative and strictly increasing"
    if times[-1] <= 0:
        return "the last point's time_from_start must be after the start"
    if goal.start_time_s is not None and not math.isfinite(goal.start_time_s):
        return "start time is not finite"
    if (moving_s := moving_until_s(times, arrays)) > MAX_MOVING_S:
        return (
            f"the trajectory moves for {moving_s:.6g} s; a goal may move for at most {MAX_MOVING_S:.0f} s "
            "(its last point may be held as long as it says)"
        )
    return ""


def moving_until_s(times_s: np.ndarray, arrays: dict[str, np.ndarray | None]) -> float:
    """When a goal's points stop moving (after its start): the time of its last point that differs from the one
    before it or has a velocity or acceleration; the first point's when none does (the way there moves)."""
    pos = arrays["positions"]
    moving = np.flatnonzero(np.any(pos[1:] != pos[:-1], axis=1)) + 1
    last = int(moving[-1]) if moving.size else 0
    for what in ("velocities", "accelerations"):
        if arrays.get(what) is not None and (nonzero := np.flatnonzero(np.any(arrays[what] != 0.0, axis=1))).size:
            last = max(last, int(nonzero[-1]))
    return float(times_s[last])


@dataclass
class Spline:
    """Positions and velocities over absolute sim time: from a start state through a goal's points, held at the end.

    With a servo period, positions and velocities at every servo tick (multiples of the period) are
    evaluated at once when the spline is built, so each tick reads them instead of calling scipy.
    """

    t0_s: float
    t_end_s: float
    poly: BPoly
    dpoly: BPoly
    ddpoly: BPoly
    q_end: np.ndarray
    period_s: float | None = None
    first_k: int = 0
    grid_q: np.ndarray | None = None
    grid_dq: np.ndarray | None = None

    @classmethod
    def through(
        cls,
        t0_s: float,
        q0: np.ndarray,
        dq0: np.ndarray,
        ddq0: np.ndarray,
        checked: CheckedGoal,
        period_s: float | None = None,
    ) -> Spline:
        """From state (q0, dq0, ddq0) at `t0_s` through the goal's points (same order of derivatives at every knot)."""
        order = 1 + (checked.velocities is not None) + (checked.accelerations is not None)
        rows = [checked.positions] + [a for a in (checked.velocities, checked.accelerations) if a is not None]
        start = [q0, dq0, ddq0][:order]
        times, points = checked.times_s, np.stack(rows, axis=1)  # (points, order, joints)
        if times[0] <= 1e-9:  # the first point is at the start: it replaces the start state
            knots, values = t0_s + times, points
        else:
            knots = np.concatenate([[t0_s], t0_s + times])
            values = np.concatenate([np.stack(start)[None], points])
        poly = BPoly.from_derivatives(knots, values)
        dpoly = poly.derivative()
        spline = cls(
            float(knots[0]), float(knots[-1]), poly, dpoly, dpoly.derivative(), checked.positions[-1].copy(), period_s
        )
        if period_s:  # while it moves: a held tail reads its end (`state`)
            k0, k1 = math.ceil(spline.t0_s / period_s - 1e-6), math.floor(spline.moves_until_s / period_s + 1e-6)
            if k1 >= k0:
                times = np.clip(np.arange(k0, k1 + 1) * period_s, spline.t0_s, spline.t_end_s)
                spline.first_k, spline.grid_q, spline.grid_dq = k0, poly(times), dpoly(times)
        return spline

    @cached_property
    def moves_until_s(self) -> float:
        """When the spline last moves: the end of its last piece whose coefficients are not all one value (a goal
        that holds its last point rests from there on; `t0_s` when it never moves)."""
        c = self.poly.c  # (order + 1, pieces, joints): Bernstein coefficients, all equal on a piece that holds
        varying = np.flatnonzero(np.any(c.max(axis=0) != c.min(axis=0), axis=-1))
        return float(self.poly.x[varying[-1] + 1]) if varying.size else self.t0_s

    def sample(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position, velocity and acceleration at `t_s` (the first point before the start, the last after the end)."""
        if t_s >= self.moves_until_s:
            return self.q_end.copy(), np.zeros_like(self.q_end), np.zeros_like(self.q_end)
        t = max(t_s, self.t0_s)
        return self.poly(t), self.dpoly(t), self.ddpoly(t)

    def q_at(self, t_s: float) -> np.ndarray:
        """Position alone at `t_s` (the first point before the start, the last after the end)."""
        if t_s >= self.moves_until_s:
            return self.q_end
        return self.poly(max(t_s, self.t0_s))

    def state(self, t_s: float) -> tuple[np.ndarray, np.ndarray]:
        """Position and velocity at `t_s`: read from the servo grid when `t_s` is on it."""
        if self.grid_q is not None:
            k = round(t_s / self.period_s)
            i = k - self.first_k
            if 0 <= i < len(self.grid_q) and abs(k * self.period_s - t_s) < 1e-9:
                if t_s >= self.moves_until_s:
                    return self.q_end, np.zeros_like(self.q_end)
                return self.grid_q[i], self.grid_dq[i]
        q, dq, _ = self.sample(t_s)
        return q, dq


def rest_to_rest(
    goal_id: int,
    joint_names: tuple[str, ...],
    q_end: np.ndarray,
    duration_s: float,
    start_time_s: float | None,
    **tolerances: tuple[float, ...],
) -> TrajectoryGoal:
    """One point at rest (zero velocity and acceleration): from a resting arm, a quintic move in `duration_s`."""
    n = len(joint_names)
    return TrajectoryGoal(
        goal_id,
        tuple(joint_names),
        (float(duration_s),),
        (tuple(map(float, q_end)),),
        ((0.0,) * n,),
        ((0.0,) * n,),
        start_time_s,
        **tolerances,
    )
