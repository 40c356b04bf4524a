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

from robots.failures import FailureCode
from robots.joint_trajectory import stopped_by_hold
from robots.phase import Phase
from robots.skills.interface import ArmObservation, PartObservation

CARRYING = (Phase.LIFT, Phase.STANDBY, Phase.TRANSFER, Phase.LOWER)  # the part in the claw, not yet let go
LET_GO = (Phase.RELEASE, Phase.RETREAT)  # the part set down: the place is done


class EStopWait:
    """Waiting out an e-stop: one concern of `PickPlaceSkill`, kept apart."""

    stopped_in: Phase | None = None  # the phase an e-stop interrupted (None: not stopped)
    estops = 0

    def _estop_ended(self, obs: ArmObservation) -> bool:
        """True when this decision's newest result is one of the skill's goals ended by the e-stop: the skill
        stops (the task is not failed) until its arm is released."""
        if not self.active or not stopped_by_hold(obs.result_reason) or obs.result_goal_id not in self.sent_goals:
            return False  # a skill with no task (one cancelled meanwhile) has nothing to wait for
        self.stopped_in = self.phase
        self.estops += 1
        self._timeline, self.request = [], None
        self.outbox.forget()
        return True

    def _waiting_out_estop(self, obs: ArmObservation, parts: dict[int, PartObservation]) -> bool:
        """While stopped: True (nothing to do) as long as the arm is held; on release, the plan is made again."""
        if self.stopped_in is None or self.job is None:
            self.stopped_in = None
            return False
        if obs.held:
            return True
        phase, self.stopped_in = self.stopped_in, None
        self._now, self.q_cmd = obs.time_s, np.asarray(obs.q, float).copy()
        if phase in LET_GO:  # the place is done: home, as it would have ended (the next approach starts there)
            self._head_home(obs.time_s)
        elif phase in CARRYING:
            self._after_lift(obs)
        elif (part := parts.get(self.job.part_id)) is not None:
            self.start(self.job, obs, part)
        else:
            self._fail(FailureCode.PART_VANISHED, f"part {self.job.part_id} left the line during the e-stop")
        return True
