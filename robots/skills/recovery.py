"""What a pick-and-place skill does when things go wrong: goals the bus lost sent again (later, the plan shifted with
them), and an arm left idle away from home sent home."""

from __future__ import annotations

import numpy as np

from robots.failures import FailureCode
from robots.joint_trajectory import ArmGoal, TrajectoryGoal
from robots.skills.interface import ArmObservation
from robots.skills.skill_plan import SkillPlan, at_home

MAX_RESENDS = 2  # a batch of goals lost again after this many sends ends the task failed

LOST_AFTER_PERIODS = 3  # a goal not seen by the tracker this many decisions after it was due there was lost on the way


class SkillRecovery:
    """Recovering `plan` from lost goals, and an idle arm away from `home_q` (after `clear_after_s`)."""

    def __init__(self, plan: SkillPlan, home_q: np.ndarray, home_tolerance_rad: float, clear_after_s: float) -> None:
        self.plan = plan
        self.home_q, self.home_tolerance_rad, self.clear_after_s = home_q, home_tolerance_rad, clear_after_s
        self.idle_since_s: float | None = None  # when the skill last stopped being active (None: active)

    def resend_lost(self, obs: ArmObservation) -> bool:
        """Goals lost on the bus: a batch whose trajectory goal the tracker has not shown (driving, or with a
        result) well after it was due there is sent again, later by as much as it must (the plan shifts with
        it); lost `MAX_RESENDS` times, the task fails. False when the task failed."""
        if obs.goal_id is None:
            return True
        plan = self.plan
        seen = max(obs.goal_id, obs.result_goal_id)
        keep = []
        for sent_s, sends, goals in plan.outbox.unconfirmed:
            newest = max(g.goal_id for g in goals if isinstance(g, TrajectoryGoal))
            if seen >= newest:
                continue
            if obs.time_s - sent_s <= plan.latency_s + LOST_AFTER_PERIODS * plan.decision_period_s:
                keep.append((sent_s, sends, goals))
                continue
            if sends > MAX_RESENDS:
                plan.fail(FailureCode.GOAL_LOST, f"trajectory goal {newest} was lost on the bus {sends} times")
                return False
            keep.append((obs.time_s, sends + 1, self._resend(goals, obs.time_s)))
        plan.outbox.unconfirmed = keep
        return True

    def _resend(self, goals: list[ArmGoal], now_s: float) -> list[ArmGoal]:
        """`goals` again with new ids, starting no sooner than a goal sent now can; the plan moves with them."""
        self.plan.now_s = now_s
        first = min(g.start_time_s for g in goals if g.start_time_s is not None)
        shift = max(0.0, self.plan.earliest() - first)
        self.plan.shift(shift)
        return self.plan.outbox.resend(goals, shift)

    def clear_the_way(self, obs: ArmObservation) -> bool:
        """An arm left standing away from home with nothing to do (its task failed mid-way, or its controller was
        restarted) would block its neighbours' grants for ever: True when it should go home now, after
        `clear_after_s` (the plan is cleared for it; a part still held drops where it is, and the line's events
        say what became of it)."""
        if self.idle_since_s is None:
            self.idle_since_s = obs.time_s
        q = np.asarray(obs.q, float)
        if obs.time_s - self.idle_since_s < self.clear_after_s - 1e-9:
            return False
        if at_home(q, self.home_q, self.home_tolerance_rad):
            return False
        plan = self.plan
        plan.now_s = obs.time_s
        plan.job, plan.failure = None, None
        plan.forget()
        plan.q_cmd = q.copy()
        self.idle_since_s = None
        return True
