"""What an arm's trajectory tracker saves: its paths (each goal as checked and its spline's coefficients), the hold
point, the claw's goals, e-stop, watchdog and counts; not what it was built with (joints, limits, servo period, the
claw's reading of its joints), which a tracker built for the same arm has already."""

from __future__ import annotations

import numpy as np
from scipy.interpolate import BPoly

from robots.gripper_tracking import GripperTracker, _Gripper
from robots.joint_trajectory import CheckedGoal, GoalResult, GripperGoal, Spline
from robots.saved_state import SavedState
from robots.tracker import ArmTracker, _Active


class SplineState(SavedState, frozen=True):
    """A `Spline`: its Bernstein polynomial (breakpoints and coefficients) and its servo grid, to the bit."""

    t0_s: float
    t_end_s: float
    breakpoints_s: np.ndarray
    coefficients: np.ndarray
    q_end: np.ndarray
    period_s: float | None
    first_k: int
    grid_q: np.ndarray | None
    grid_dq: np.ndarray | None


class PathState(SavedState, frozen=True):
    """A trajectory goal the tracker follows or will: the goal as checked, its spline, whether its result is out."""

    checked: CheckedGoal
    spline: SplineState
    ended: bool


class ClawGoalState(SavedState, frozen=True):
    goal: GripperGoal
    start_s: float
    still_since_s: float | None


class ClawState(SavedState, frozen=True):
    """A `GripperTracker`'s goals, opening and effort."""

    running: ClawGoalState | None
    waiting: ClawGoalState | None
    opening: float
    effort_n: float


class TrackerState(SavedState, frozen=True):
    """An `ArmTracker`'s state (`tracker_state`, `restore_tracker`)."""

    hold_q: np.ndarray
    active: PathState | None
    next: PathState | None
    estop: bool
    watchdog_deadline_s: float
    clamped: int
    last: GoalResult | None
    desired_q: np.ndarray
    desired_dq: np.ndarray
    desired_holds: bool  # the last targets are the hold point itself (held again without being written)
    claw: ClawState


def spline_state(s: Spline) -> SplineState:
    return SplineState(
        t0_s=s.t0_s,
        t_end_s=s.t_end_s,
        breakpoints_s=np.asarray(s.poly.x),
        coefficients=np.asarray(s.poly.c),
        q_end=s.q_end,
        period_s=s.period_s,
        first_k=s.first_k,
        grid_q=s.grid_q,
        grid_dq=s.grid_dq,
    )


def spline_of(s: SplineState) -> Spline:
    """The spline back, its derivatives taken again from the same coefficients (so evaluated to the bit)."""
    poly = BPoly(s.coefficients, s.breakpoints_s)
    dpoly = poly.derivative()
    return Spline(
        s.t0_s, s.t_end_s, poly, dpoly, dpoly.derivative(), s.q_end, s.period_s, s.first_k, s.grid_q, s.grid_dq
    )


def path_state(a: _Active | None) -> PathState | None:
    if a is None:
        return None
    return PathState(checked=a.checked, spline=spline_state(a.spline), ended=a.ended)


def path_of(s: PathState | None) -> _Active | None:
    if s is None:
        return None
    return _Active(s.checked, spline_of(s.spline), s.ended)


def _claw_goal_state(g: _Gripper | None) -> ClawGoalState | None:
    return None if g is None else ClawGoalState(goal=g.goal, start_s=g.start_s, still_since_s=g.still_since_s)


def _claw_goal_of(s: ClawGoalState | None) -> _Gripper | None:
    return None if s is None else _Gripper(s.goal, s.start_s, s.still_since_s)


def claw_state(claw: GripperTracker) -> ClawState:
    return ClawState(
        running=_claw_goal_state(claw.running),
        waiting=_claw_goal_state(claw.waiting),
        opening=claw.opening,
        effort_n=claw.effort_n,
    )


def restore_claw(claw: GripperTracker, s: ClawState) -> None:
    claw.running, claw.waiting = _claw_goal_of(s.running), _claw_goal_of(s.waiting)
    claw.opening, claw.effort_n = s.opening, s.effort_n


def tracker_state(t: ArmTracker) -> TrackerState:
    """What `t` saves."""
    q, dq = t.desired_now
    return TrackerState(
        hold_q=t.hold_q,
        active=path_state(t.active),
        next=path_state(t.next),
        estop=t.estop,
        watchdog_deadline_s=t.watchdog_deadline_s,
        clamped=t.clamped,
        last=t.last,
        desired_q=q,
        desired_dq=dq,
        desired_holds=q is t.hold_q,
        claw=claw_state(t.claw),
    )


def restore_tracker(t: ArmTracker, s: TrackerState) -> None:
    """Put a saved state back into `t`, a tracker built for the same arm."""
    t.hold_q = s.hold_q.copy()
    t.active, t.next = path_of(s.active), path_of(s.next)
    t.estop, t.watchdog_deadline_s, t.clamped, t.last = s.estop, s.watchdog_deadline_s, s.clamped, s.last
    t.desired_now = (t.hold_q if s.desired_holds else s.desired_q.copy(), s.desired_dq.copy())
    restore_claw(t.claw, s.claw)
