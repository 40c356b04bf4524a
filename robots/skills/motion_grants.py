"""A pick-and-place skill's free moves asked for and answered: the request it holds still for (with the local stage
after it), a grant, a denial (a detour home, a wait), a stand-by beside a place that is not ready."""

from __future__ import annotations

import numpy as np

from robots.failures import FailureCode
from robots.phase import Phase
from robots.skills.interface import MotionRequest
from robots.skills.pick_geometry import ClawGeometry
from robots.skills.pick_plans import PickPlans
from robots.skills.skill_plan import SkillPlan, at_home
from robots.spec import RobotSpec
from robots.trajectory import JointSegment


class MotionGrants:
    """Begins each free move of `plan`: sent at once, or with grants `required`, asked for first (the arm holds
    still until `on_grant` answers). `plans` works out the stage after a move and a stand-by; `timing` is a
    `PickPlaceTiming`."""

    def __init__(
        self, plan: SkillPlan, plans: PickPlans, spec: RobotSpec, geometry: ClawGeometry, timing, required: bool
    ) -> None:
        self.plan, self.plans, self.spec, self.geometry, self.timing = plan, plans, spec, geometry, timing
        self.required = required
        self.request_seq = 0
        self.denials = self.standbys = self.detours = 0
        self.denied_since_s: float | None = None  # when the current free move was first denied
        self.detour_to: np.ndarray | None = None  # a denied transfer's end, while the arm detours home first
        self.stood_by = False  # this task's transfer was told to stand by (once a task)
        self.transfer_to: np.ndarray | None = None  # the transfer's end, while the arm stands by
        self.then_cache: tuple = (None, ([], []))  # the local stage of the move last asked for

    def new_task(self) -> None:
        """A task begins: no detour, no stand-by yet."""
        self.detour_to = None
        self.stood_by, self.transfer_to = False, None

    def begin(self, segment: JointSegment, phase: Phase, time_s: float) -> None:
        """Enter a free move; with grants required, ask for it first and hold still until answered."""
        plan = self.plan
        plan.splice(segment, time_s)
        plan.enter(phase, time_s)
        plan.request = None
        self.denied_since_s = None
        if self.required:
            self.ask(time_s)
        else:
            plan.go(time_s)

    def head_home(self, time_s: float) -> None:
        self.begin(self.plans.home(time_s), Phase.HOME, time_s)

    def ask(self, time_s: float) -> None:
        plan = self.plan
        self.request_seq += 1
        seg = plan.segment
        key = (plan.phase, tuple(np.round(seg.q_end, 9)))
        if self.then_cache[0] != key:
            self.then_cache = (key, self.plans.local_stage_after(seg.q_end, detouring=self.detour_to is not None))
        then_after_s, then_q = self.then_cache[1]
        plan.request = MotionRequest(
            self.request_seq,
            tuple(map(float, plan.q_cmd)),
            tuple(map(float, seg.q_end)),
            float(seg.duration_s),
            time_s,
            tuple(tuple(map(float, q)) for q in then_q),
            tuple(then_after_s),
        )

    def on_grant(
        self, request_seq: int, decision: str, conflict_arm: str, time_s: float, start_time_s: float | None = None
    ) -> None:
        """The coordinator's answer to request `request_seq` (stale answers are ignored): grant (from `start_time_s`,
        else now), or deny naming the arm in the way."""
        plan = self.plan
        if plan.request is None or request_seq != plan.request.seq or not plan.active:
            return
        plan.now_s = time_s
        if decision == "grant":
            plan.request = None
            plan.go(max(time_s, start_time_s if start_time_s is not None else time_s))
            return
        if decision == "standby":  # the place is not ready: wait beside it, then ask to place from there
            plan.request = None
            self._stand_by(time_s)
            return
        self.denials += 1
        if self.denied_since_s is None:
            self.denied_since_s = time_s
        if plan.phase == Phase.APPROACH:  # nothing in hand: give the task back, the coordinator decides again
            plan.fail(
                FailureCode.MOTION_DENIED,
                f"motion denied: the approach would pass within the margin of {conflict_arm or 'another arm'}",
            )
        elif plan.phase == Phase.STANDBY:  # the spot beside the place is in another arm's way: wait where it is
            self.transfer_from_here(time_s)
        elif self._should_detour(time_s):  # the way stays blocked: make room by going home, then transfer from there
            self._detour_home(time_s)
        else:  # a part in the claw, or on the way home: ask again
            self.ask(time_s)

    def end_detour(self, time_s: float) -> None:
        """Home reached on a detour: the transfer again, from there."""
        q_to, self.detour_to = self.detour_to, None
        self._transfer(q_to, time_s)

    def transfer_from_here(self, time_s: float) -> None:
        """The transfer to above the place, from where the arm is (after standing by, or instead of it)."""
        q_to, self.transfer_to = self.transfer_to, None
        self._transfer(q_to, time_s)

    def _stand_by(self, time_s: float) -> None:
        """Told to stand by (once a task, a transfer only): move beside the place (`PickPlans.standby`), and from
        there ask for the transfer again. Where that spot cannot be reached, the transfer is asked for again from
        here."""
        plan = self.plan
        if plan.phase != Phase.TRANSFER or self.detour_to is not None or self.stood_by or plan.job is None:
            self.ask(time_s)
            return
        self.stood_by, self.transfer_to = True, plan.segment.q_end.copy()
        segment = self.plans.standby(self.transfer_to, time_s)
        if segment is None:
            self.transfer_from_here(time_s)
            return
        self.standbys += 1
        self.begin(segment, Phase.STANDBY, time_s)

    def _transfer(self, q_to: np.ndarray, time_s: float) -> None:
        """A transfer-phase free move from where the arm is to `q_to`, part in hand."""
        segment = self.geometry.segment(self.plan.q_cmd, q_to, time_s, self.timing.transfer_speed)
        self.begin(segment, Phase.TRANSFER, time_s)

    def _should_detour(self, time_s: float) -> bool:
        """Two arms each standing in the other's way (one waiting to transfer, one to go home or transfer) would
        wait for ever; the transfer that has waited `detour_after_s` gives way."""
        t = self.timing
        return (
            self.plan.phase == Phase.TRANSFER
            and self.detour_to is None
            and not at_home(self.plan.q_cmd, self.spec.home_q, t.home_tolerance_rad)
            and time_s - self.denied_since_s >= t.detour_after_s - 1e-9
        )

    def _detour_home(self, time_s: float) -> None:
        self.detour_to = self.plan.segment.q_end.copy()
        self.detours += 1
        self._transfer(np.asarray(self.spec.home_q, float), time_s)
