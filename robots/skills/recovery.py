"""What a pick-and-place skill does when things go wrong: goals the bus lost sent again (later, the plan shifted with
them), and an arm left idle away from home sent home."""

from __future__ import annotations

import numpy as np

from robots.failures import FailureCode
from robots.joint_trajectory import ArmGoal, TrajectoryGoal
from robots.skills.interface import ArmObservation

MAX_RESENDS = 2  # a batch of goals lost again after this many sends ends the task failed

LOST_AFTER_PERIODS = 3  # a goal not seen by the tracker this many decisions after it was due there was lost on the way


class SkillRecovery:
    """Recovering from lost goals and idle arms away from home: one concern of `PickPlaceSkill`, kept apart."""

    def _resend_lost(self, obs: ArmObservation) -> bool:
        """Goals lost on the bus: a batch whose trajectory goal the tracker has not shown (driving, or with a
        result) well after it was due there is sent again, later by as much as it must (the plan shifts with
        it); lost `MAX_RESENDS` times, the task fails. False when the task failed."""
        if obs.goal_id is None:
            return True
        seen = max(obs.goal_id, obs.result_goal_id)
        keep = []
        for sent_s, sends, goals in self.outbox.unconfirmed:
            newest = max(g.goal_id for g in goals if isinstance(g, TrajectoryGoal))
            if seen >= newest:
                continue
            if obs.time_s - sent_s <= self.latency_s + LOST_AFTER_PERIODS * self.decision_period_s:
                keep.append((sent_s, sends, goals))
                continue
            if sends > MAX_RESENDS:
                self._fail(FailureCode.GOAL_LOST, f"trajectory goal {newest} was lost on the bus {sends} times")
                return False
            keep.append((obs.time_s, sends + 1, self._resend(goals, obs.time_s)))
        self.outbox.unconfirmed = keep
        return True

    def _resend(self, goals: list[ArmGoal], now_s: float) -> list[ArmGoal]:
        """`goals` again with new ids, starting no sooner than a goal sent now can; the plan moves with them."""
        self._now = now_s
        first = min(g.start_time_s for g in goals if g.start_time_s is not None)
        shift = max(0.0, self._earliest() - first)
        self.plan_end_s += shift
        self._timeline = [(t + shift, p) for t, p in self._timeline]
        return self.outbox.resend(goals, shift)

    def _clear_the_way(self, obs: ArmObservation) -> None:
        """An arm left standing away from home with nothing to do (its task failed mid-way, or its controller was
        restarted) would block its neighbours' grants for ever: after `clear_after_s` it goes home, claw open
        (a part still held drops where it is, and the line's events say what became of it)."""
        if self._idle_since_s is None:
            self._idle_since_s = obs.time_s
        q = np.asarray(obs.q, float)
        if obs.time_s - self._idle_since_s < self.timing.clear_after_s - 1e-9:
            return
        if self._at_home(q):
            return
        self._now = obs.time_s
        self.job, self.failure = None, None
        self._timeline = []
        self.outbox.forget()
        self.q_cmd = q.copy()
        self._idle_since_s = None
        self._head_home(obs.time_s)
