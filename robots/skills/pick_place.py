"""Pick a part (from a moving conveyor or a still surface) and place it: the bridge layer's skill.

Primitives, in order: approach above the part's predicted position, descend
while following it, close, lift, transfer, lower, release, retreat, home. The
skill speaks in trajectory goals (`robots.joint_trajectory`), as a ROS arm's
planner speaks FollowJointTrajectory to its joint trajectory controller: free
moves (approach, transfer, home) are rest-to-rest quintic goals; the grasp
(descend, close, lift) and the place (lower, release, retreat) are each one goal
through Cartesian knots solved with Pinocchio IK, with gripper goals timed
inside them. The tracker (`robots.tracker`) follows them at the servo rate; the
skill decides at its own rate and plans the next local stage one decision ahead,
so stages join without a pause. The grasp is a friction grasp made by the
physics: this code only plans joint motion and claw openings.

With `grants_required`, each free move is first asked for: the skill holds with a
`MotionRequest` out until `on_grant` answers. A denied approach ends the task
failed (the coordinator may give it again); a denied transfer or return home is
asked for again. An approach kept waiting past `REPLAN_AFTER_S` is planned again
from where the part is by then. A goal the tracker aborts (path tolerance, e-stop,
watchdog) or refuses ends the task failed with its reason.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from robots.failures import Failure, FailureCode
from robots.joint_trajectory import ArmGoal
from robots.kinematics import KinematicModel
from robots.phase import ORDER, Phase
from robots.skills.estop_wait import CARRYING, LET_GO, EStopWait
from robots.skills.goal_outbox import GoalOutbox
from robots.skills.interface import ArmObservation, MotionRequest, PartObservation, PickPlaceJob
from robots.skills.motion_grants import MotionGrants
from robots.skills.pick_geometry import ClawGeometry
from robots.skills.pick_plans import PickPlans
from robots.skills.recovery import SkillRecovery
from robots.skills.skill_plan import SkillPlan
from robots.spec import RobotSpec
from robots.top_down import TopDownIK

DEFAULT_DECISION_HZ = 20.0  # a controller's decisions per sim second, unless it asks for another rate
REPLAN_AFTER_S = 0.3
FAILED_STATUSES = ("aborted", "rejected")


@dataclass(frozen=True)
class PickPlaceTiming:
    """Durations (s) and clearances (m) of the primitives."""

    hover_m: float = 0.08
    descend_s: float = 0.6
    close_s: float = 0.45
    lift_s: float = 0.5
    lift_m: float = 0.12
    lower_s: float = 0.45
    release_s: float = 0.3
    retreat_s: float = 0.3
    track_lead_s: float = 0.02
    approach_speed: float = 1.0  # fractions of each joint's velocity limit, reached at a move's peak (quintic timing)
    transfer_speed: float = 1.0
    pregrasp_clearance_m: float = 0.024
    fixed_jaw_gap_m: float = 0.0  # a gripper with a fixed jaw: how far clear of the part's face that jaw comes down
    place_drop_m: float = 0.008
    clear_after_s: float = 1.0  # an arm idle this long away from home (a failed task, a respawned controller) goes home
    home_tolerance_rad: float = 0.05  # within this of the home pose on every joint counts as home
    # a transfer denied this long goes home first (the arm in the way may be waiting for it)
    detour_after_s: float = 2.0
    # told to stand by: this fraction of the way from the place's hover point to the arm's base...
    standby_back: float = 0.8
    standby_up_m: float = 0.08  # ...and this much higher

    @classmethod
    def for_robot(cls, spec: RobotSpec) -> PickPlaceTiming:
        """The default timing with the robot's own values (`RobotSpec.pick_timing`)."""
        return dataclasses.replace(cls(), **spec.pick_timing)


class PickPlaceSkill:
    """State machine for one pick-and-place: `start`, then `step` at the decision rate; both queue goals that `step`
    returns.

    `decision_period_s` is how often `step` is called; `latency_s` how long after a decision its goals
    reach the tracker (a controller's answer takes effect at its next due tick: one period, the
    default). Every goal carries an absolute start time at least that far ahead, so the arm moves
    the same in process and over the bus; the next local stage is planned when the current one
    ends within a period plus the latency, so it is spliced in at the current one's end.

    It wires its concerns around one `SkillPlan`: `plans` (the stages planned), `grants` (free moves asked for),
    `estop` (an e-stop waited out) and `recovery` (lost goals, an idle arm away from home).
    """

    def __init__(
        self,
        spec: RobotSpec,
        transform_base_to_world: np.ndarray,
        *,
        timing: PickPlaceTiming | None = None,
        model: KinematicModel | None = None,
        grants_required: bool = False,
        decision_period_s: float = 1.0 / DEFAULT_DECISION_HZ,
        latency_s: float | None = None,
    ) -> None:
        self.spec, self.timing = spec, timing if timing is not None else PickPlaceTiming.for_robot(spec)
        self.km = model or KinematicModel(spec)
        self.top_down = TopDownIK(spec, transform_base_to_world, self.km)
        self.geometry = ClawGeometry(spec, self.top_down, self.km)
        self.outbox = GoalOutbox(tuple(spec.arm_joints))
        latency_s = decision_period_s if latency_s is None else latency_s
        self.plan = SkillPlan(self.outbox, self.km.arm_velocity_limit, decision_period_s, latency_s)
        self.plans = PickPlans(self.plan, spec, self.geometry, self.timing)
        self.grants = MotionGrants(self.plan, self.plans, spec, self.geometry, self.timing, grants_required)
        self.estop = EStopWait(self.plan)
        home_q = np.asarray(spec.home_q, float)
        self.recovery = SkillRecovery(self.plan, home_q, self.timing.home_tolerance_rad, self.timing.clear_after_s)

    # --- what others read -------------------------------------------------------------
    @property
    def phase(self) -> Phase:
        """The phase of the current (or last) task."""
        return self.plan.phase

    @property
    def job(self) -> PickPlaceJob | None:
        return self.plan.job

    @property
    def failure(self) -> Failure | None:
        """Why the last task failed (None: it did not)."""
        return self.plan.failure

    @property
    def request(self) -> MotionRequest | None:
        """The free move asked for and not yet answered."""
        return self.plan.request

    @property
    def active(self) -> bool:
        return self.plan.active

    @property
    def goal_id(self) -> int:
        """The id of the last goal sent (a controller starts its count where a respawn cannot repeat one)."""
        return self.outbox.goal_id

    @goal_id.setter
    def goal_id(self, value: int) -> None:
        self.outbox.goal_id = value

    @property
    def sent_goals(self) -> set[int]:
        return self.outbox.sent

    @property
    def goals_resent(self) -> int:
        return self.outbox.resent

    @property
    def failure_reason(self) -> str:
        """The sentence of the last failure ("" when none)."""
        return self.plan.failure.reason if self.plan.failure else ""

    @property
    def failure_code(self) -> str:
        """The code of the last failure ("" when none), as the bus carries it."""
        return self.plan.failure.code.value if self.plan.failure else ""

    @property
    def progress(self) -> float:
        """Fraction of the primitives done, for status reports."""
        if self.phase == Phase.DONE:
            return 1.0
        phase = Phase.TRANSFER if self.phase == Phase.STANDBY else self.phase
        return ORDER.index(phase) / len(ORDER) if phase in ORDER else 0.0

    @property
    def available(self) -> bool:
        """Free to start a task: idle, or on the way home (given up for the next task's approach, which the
        tracker splices in where the way home has got to)."""
        return not self.active or self.phase == Phase.HOME

    # --- orders -------------------------------------------------------------------------
    def start(self, job: PickPlaceJob, obs: ArmObservation, part: PartObservation) -> None:
        """Begin a pick of `part`; fails at once, with a reason, if the part cannot be reached."""
        plan = self.plan
        plan.now_s = obs.time_s
        self.recovery.idle_since_s = None
        self.grants.new_task()
        plan.job, plan.failure, self.estop.stopped_in = job, None, None
        plan.forget()
        plan.q_cmd = np.asarray(obs.q, float).copy()
        self.plans.begin(job, part)
        self._plan_approach(obs, part)

    def on_grant(
        self, request_seq: int, decision: str, conflict_arm: str, time_s: float, start_time_s: float | None = None
    ) -> None:
        """The coordinator's answer to request `request_seq` (`MotionGrants.on_grant`)."""
        self.grants.on_grant(request_seq, decision, conflict_arm, time_s, start_time_s)

    def reject(self, reason: str) -> None:
        """Refuse a task before starting it (the part is unknown): the skill ends failed with `reason`."""
        self.plan.fail(FailureCode.REJECTED, reason)

    def cancel(self, reason: str) -> None:
        """Stop the current task; the arm finishes the goal it is on and holds there with the claw as it is (a task
        waiting out a hold is dropped: nothing is planned again on release)."""
        self.estop.stopped_in = None
        self.plan.fail(FailureCode.CANCELLED, reason)

    # --- each decision --------------------------------------------------------------
    def step(self, obs: ArmObservation, parts: dict[int, PartObservation]) -> list[ArmGoal]:
        """One decision at `obs.time_s`: the goals to send now (often none: the tracker is following the plan)."""
        if self.active:
            self._decide(obs, parts)
        elif self.recovery.clear_the_way(obs):
            self.grants.head_home(obs.time_s)
        return self.outbox.take(obs.time_s, watched=obs.goal_id is not None)

    def _decide(self, obs: ArmObservation, parts: dict[int, PartObservation]) -> None:
        plan = self.plan
        now = plan.now_s = obs.time_s
        if self._resumed_after_estop(obs, parts) or self.estop.stopped_now(obs):
            return
        if obs.result_goal_id in self.sent_goals and obs.result_status in FAILED_STATUSES:
            refused = plan.phase == Phase.APPROACH and obs.result_status == "rejected"  # nothing touched: no attempt
            plan.fail(
                FailureCode.MOTION_DENIED if refused else FailureCode.GOAL_FAILED,
                f"trajectory goal {obs.result_goal_id} {obs.result_status}: {obs.result_reason}",
            )
            return
        if not self.recovery.resend_lost(obs):
            return
        plan.enter_due(now)
        part = parts.get(plan.job.part_id) if plan.job is not None else None
        if plan.request is not None:  # holding for a grant
            if plan.phase == Phase.APPROACH and part is not None and now - plan.request.asked_at_s > REPLAN_AFTER_S:
                self._plan_approach(obs, part)  # the part moved on: a fresh plan, asked for again
            return
        if plan.timeline:
            return
        self._next_stage(obs, part, ahead=plan.plan_end_s - now)

    def _next_stage(self, obs: ArmObservation, part: PartObservation | None, ahead: float) -> None:
        """Plan what follows when the motion planned so far runs `ahead` seconds more: a local stage as soon as its
        goals would otherwise come too late, a free move once the arm has got there."""
        now, phase = obs.time_s, self.plan.phase
        horizon = self.plan.decision_period_s + self.plan.latency_s + 1e-9
        if self.grants.detour_to is not None:  # home reached on a detour: the transfer again, from there
            if ahead <= 1e-9:
                self.grants.end_detour(now)
            return
        if phase == Phase.STANDBY and ahead <= 1e-9:
            self.grants.transfer_from_here(now)
        elif phase == Phase.APPROACH and ahead <= horizon:
            self.plans.grasp(part, now)
        elif phase == Phase.TRANSFER and ahead <= horizon:
            self.plans.place()
        elif ahead <= 1e-9:
            if phase == Phase.LIFT:
                self._after_lift(obs)
            elif phase == Phase.RETREAT:
                self.grants.head_home(now)
            elif phase == Phase.HOME:
                self.plan.phase = Phase.DONE

    def _resumed_after_estop(self, obs: ArmObservation, parts: dict[int, PartObservation]) -> bool:
        """While an e-stop holds the arm: True (nothing to do); on release, the plan made again from the phase it
        interrupted."""
        if self.estop.held(obs):
            return True
        phase = self.estop.release(obs)
        if phase is None:
            return False
        job = self.plan.job
        if phase in LET_GO:  # the place is done: home, as it would have ended (the next approach starts there)
            self.grants.head_home(obs.time_s)
        elif phase in CARRYING:
            self._after_lift(obs)
        elif (part := parts.get(job.part_id)) is not None:
            self.start(job, obs, part)
        else:
            self.plan.fail(FailureCode.PART_VANISHED, f"part {job.part_id} left the line during the e-stop")
        return True

    def _plan_approach(self, obs: ArmObservation, part: PartObservation) -> None:
        segment = self.plans.approach(obs, part)
        if segment is not None:
            self.grants.begin(segment, Phase.APPROACH, obs.time_s)

    def _after_lift(self, obs: ArmObservation) -> None:
        segment = self.plans.transfer_after_lift(obs)
        if segment is not None:
            self.grants.begin(segment, Phase.TRANSFER, obs.time_s)
