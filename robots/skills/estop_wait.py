"""What a pick-and-place skill does through an emergency stop (or while an outside client drives its arm): it
waits, then carries on.

An e-stop aborts every goal and holds the arm (the tracker refuses goals while it lasts). That is not the task's
failure: the skill sends nothing while its arm is held and, once it is released, plans again from where the arm
stands: the pick from the start if the part was not yet in the claw, the transfer if it was, the way home if it
was let go (as the place would have ended: an approach from the bin's low pose swings the base joint farther than
its drive follows in the approach's time, and the tracker aborts it off its path). No attempt is spent on it.
"""

from __future__ import annotations

import numpy as np

from robots.joint_trajectory import stopped_by_hold
from robots.phase import Phase
from robots.skills.interface import ArmObservation
from robots.skills.skill_plan import SkillPlan

CARRYING = (Phase.LIFT, Phase.STANDBY, Phase.TRANSFER, Phase.LOWER)  # the part in the claw, not yet let go
LET_GO = (Phase.RELEASE, Phase.RETREAT)  # the part set down: the place is done


class EStopWait:
    """Waiting out an e-stop: notices the skill's goals ended by one, holds the plan while the arm is held, and on
    release says which phase was interrupted (the skill plans again from it)."""

    def __init__(self, plan: SkillPlan) -> None:
        self.plan = plan
        self.stopped_in: Phase | None = None  # the phase an e-stop interrupted (None: not stopped)
        self.estops = 0

    def stopped_now(self, obs: ArmObservation) -> bool:
        """True when this decision's newest result is one of the skill's goals ended by the e-stop: the skill
        stops (the task is not failed) until its arm is released."""
        plan = self.plan
        if not plan.active or not stopped_by_hold(obs.result_reason) or obs.result_goal_id not in plan.outbox.sent:
            return False  # a skill with no task (one cancelled meanwhile) has nothing to wait for
        self.stopped_in = plan.phase
        self.estops += 1
        plan.request = None
        plan.forget()
        return True

    def held(self, obs: ArmObservation) -> bool:
        """Stopped, with a task, and the arm still held: nothing to do."""
        if self.plan.job is None:
            self.stopped_in = None
        return self.stopped_in is not None and obs.held

    def release(self, obs: ArmObservation) -> Phase | None:
        """The phase the e-stop interrupted, once the arm is free again (None: not stopped); the plan starts again
        from where the arm stands."""
        phase, self.stopped_in = self.stopped_in, None
        if phase is not None:
            self.plan.now_s, self.plan.q_cmd = obs.time_s, np.asarray(obs.q, float).copy()
        return phase
