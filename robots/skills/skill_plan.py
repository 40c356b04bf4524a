"""A pick-and-place skill's plan: its task, the phase it is in and the phases planned to begin later, the motion sent
last and when it ends, the grant it holds still for; and the sending of its goals, each far enough ahead to reach
the tracker in time (`GoalOutbox`). The skill's concerns (planning, grants, e-stops, recovery) share this one
object, each handed it, none holding the skill."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from robots.failures import Failure, FailureCode
from robots.phase import Phase
from robots.skills.goal_outbox import GoalOutbox
from robots.skills.interface import MotionRequest, PickPlaceJob
from robots.trajectory import JointSegment, spliced, within_velocity_limits


@dataclass
class SkillPlan:
    """What the skill has planned and sent, and how far ahead a goal must be sent (`latency_s`)."""

    outbox: GoalOutbox
    velocity_limit: np.ndarray  # each arm joint's (rad/s): a move spliced into the one sent last keeps under it
    decision_period_s: float
    latency_s: float
    now_s: float = 0.0  # the time of the decision being made
    phase: Phase = Phase.IDLE
    phase_t0: float = 0.0
    failure: Failure | None = None  # why the last task failed
    job: PickPlaceJob | None = None
    timeline: list[tuple[float, Phase]] = field(default_factory=list)  # phases planned to begin at later times
    plan_end_s: float = 0.0  # when the motion planned so far ends
    q_cmd: np.ndarray | None = None  # the joints last commanded, and the free move asked for or sent last
    segment: JointSegment | None = None  # (None until the first task)
    moving: JointSegment | None = None  # the free move sent last (another may be spliced into it)
    request: MotionRequest | None = None  # the free move asked for and not yet answered

    @property
    def active(self) -> bool:
        return self.phase not in (Phase.IDLE, Phase.DONE, Phase.FAILED)

    def earliest(self, start_s: float | None = None) -> float:
        """The earliest a goal sent now can start: once it has reached the tracker."""
        soonest = self.now_s + self.latency_s
        return soonest if start_s is None else max(start_s, soonest)

    def enter(self, phase: Phase, time_s: float) -> None:
        self.phase, self.phase_t0 = phase, time_s

    def enter_due(self, now_s: float) -> None:
        """Enter the planned phases whose time has come."""
        while self.timeline and self.timeline[0][0] <= now_s + 1e-9:
            self.enter(self.timeline[0][1], self.timeline[0][0])
            self.timeline.pop(0)

    def fail(self, code: FailureCode, reason: str) -> None:
        self.phase, self.failure = Phase.FAILED, Failure(code, reason)
        self.request = None
        self.timeline = []

    def forget(self) -> None:
        """Drop what was planned ahead and the goals not yet confirmed (the motion in progress runs on)."""
        self.timeline = []
        self.outbox.forget()

    def shift(self, by_s: float) -> None:
        """Everything planned ahead, later by `by_s` (its goals were sent again that much later)."""
        self.plan_end_s += by_s
        self.timeline = [(t + by_s, p) for t, p in self.timeline]

    def splice(self, segment: JointSegment, time_s: float) -> None:
        """Make `segment` the free move to ask for or send next, joined to the one sent last."""
        self.segment = spliced(self.moving, segment, self.earliest(time_s), self.velocity_limit)[0]

    def go(self, start_s: float) -> None:
        """Send the free move, starting at `start_s` (or as soon as it can)."""
        seg, start_s = spliced(self.moving, self.segment, self.earliest(start_s), self.velocity_limit)
        self.segment = self.moving = JointSegment(seg.q_start, seg.q_end, start_s, seg.duration_s)
        self.outbox.move(seg.q_end, seg.duration_s, start_s)
        if self.phase == Phase.HOME:
            self.send_gripper(1.0, start_s)
        self.phase_t0 = start_s
        self.q_cmd, self.plan_end_s = seg.q_end.copy(), start_s + seg.duration_s

    def send_gripper(self, opening: float, start_s: float | None) -> None:
        self.outbox.gripper(opening, self.earliest(start_s))

    def send_knots(self, start_s: float, times_s: np.ndarray, qs: np.ndarray) -> Callable[[float], float]:
        """Send a knot path, stretched where it would break a joint's velocity limit; returns the map from a
        planned time to when the stretched path gets there."""
        sent = within_velocity_limits(self.q_cmd, times_s, qs, self.velocity_limit)
        self.outbox.knots(start_s, sent, qs)
        planned = np.concatenate([[0.0], np.asarray(times_s, float)])
        stretched = np.concatenate([[0.0], sent])
        return lambda t_s: float(np.interp(t_s, planned, stretched))


def at_home(q: np.ndarray, home_q: np.ndarray, tolerance_rad: float) -> bool:
    """Every joint of `q` within `tolerance_rad` of the home pose."""
    return bool(np.max(np.abs(np.asarray(q, float) - np.asarray(home_q, float))) <= tolerance_rad)
