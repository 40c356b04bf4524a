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
from robots.skills.estop_wait import EStopWait
from robots.skills.goal_outbox import GoalOutbox
from robots.skills.interface import ArmObservation, MotionRequest, PartObservation, PickPlaceJob
from robots.skills.motion_grants import MotionGrants
from robots.skills.pick_geometry import ClawGeometry
from robots.skills.pick_plans import PickPlans
from robots.skills.recovery import SkillRecovery
from robots.spec import RobotSpec
from robots.top_down import TopDownIK
from robots.trajectory import JointSegment, spliced

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


class PickPlaceSkill(EStopWait, SkillRecovery, PickPlans, MotionGrants):
    """State machine for one pick-and-place: `start`, then `step` at the decision rate; both queue goals that `step`
    returns.

    `decision_period_s` is how often `step` is called; `latency_s` how long after a decision its goals
    reach the tracker (a controller's answer takes effect at its next due tick: one period, the
    default). Every goal carries an absolute start time at least that far ahead, so the arm moves
    the same in process and over the bus; the next local stage is planned when the current one
    ends within a period plus the latency, so it is spliced in at the current one's end.
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
        self.grants_required = grants_required
        self.decision_period_s = decision_period_s
        self.latency_s = decision_period_s if latency_s is None else latency_s
        self._now = 0.0
        self.request: MotionRequest | None = None
        self._request_seq = 0
        self.denials = 0
        self.km = model or KinematicModel(spec)
        self.top_down = TopDownIK(spec, transform_base_to_world, self.km)
        self.geometry = ClawGeometry(spec, self.top_down, self.km)
        self.phase = Phase.IDLE
        self.failure: Failure | None = None  # why the last task failed
        self.job: PickPlaceJob | None = None
        self.ik_failures = 0
        self.outbox = GoalOutbox(tuple(spec.arm_joints))
        self._timeline: list[tuple[float, Phase]] = []  # phases planned to begin at later times
        self.plan_end_s = 0.0
        self._moving: JointSegment | None = None  # the free move sent last (another may be spliced into it)
        self.missed_yaws: dict[int, list[float]] = {}  # part id -> the grasp yaws that closed on nothing
        self.phase_t0 = 0.0
        self._idle_since_s: float | None = None  # when the skill last stopped being active (None: active)
        self._denied_since_s: float | None = None  # when the current free move was first denied
        self._detour_to: np.ndarray | None = None  # a denied transfer's end, while the arm detours home first
        self._stood_by = False  # this task's transfer was told to stand by (once a task)
        self._transfer_to: np.ndarray | None = None  # the transfer's end, while the arm stands by
        self.standbys = 0
        self._then_cache: tuple = (None, ([], []))  # the local stage of the move last asked for
        self.place_yaw = 0.0
        self.pick_tilt_rad = self.place_tilt_rad = 0.0  # how far the claw leans from straight down at each end
        # where the part sits between the jaws, tool frame (off centre: one fixed jaw)
        self.grasp_centre = (0.0, 0.0, 0.0)
        self._grasp_world = np.zeros(3)
        # the way the claw rises from the part, from the place
        self._pick_up = self._place_up = np.array([0.0, 0.0, 1.0])
        self.detours = 0
        self.q_cmd: np.ndarray | None = None  # the joints last commanded, and the free move asked for or sent last
        self.segment: JointSegment | None = None  # (None until the first task)
        self.grasp_yaw = self.grasp_z = self.tool_above_bottom_m = self.pregrasp_opening = self.part_height = 0.0
        self.velocity = np.zeros(3)  # the surface's, and the grasp on the line above: set when a task starts

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(self.spec.arm_joints)

    # --- goals out ------------------------------------------------------------------
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

    def _send_move(self, q_end: np.ndarray, duration_s: float, start_s: float) -> None:
        self.outbox.move(q_end, duration_s, start_s)

    def _earliest(self, start_s: float | None = None) -> float:
        """The earliest a goal sent now can start: once it has reached the tracker."""
        soonest = self._now + self.latency_s
        return soonest if start_s is None else max(start_s, soonest)

    def _send_gripper(self, opening: float, start_s: float | None) -> None:
        self.outbox.gripper(opening, self._earliest(start_s))

    # --- the state machine ----------------------------------------------------------
    def start(self, job: PickPlaceJob, obs: ArmObservation, part: PartObservation) -> None:
        """Begin a pick of `part`; fails at once, with a reason, if the part cannot be reached."""
        t = self.timing
        self._now = obs.time_s
        self._idle_since_s = None
        self._detour_to = None
        self._stood_by, self._transfer_to = False, None
        self.job, self.failure, self.stopped_in = job, None, None
        self.outbox.forget()
        self._timeline = []
        self.q_cmd = np.asarray(obs.q, float).copy()
        self.grasp_yaw = self.geometry.grasp_yaw(part, self.missed_yaws.get(part.part_id, ()))
        self.grasp_centre = self.spec.grasp_centre_tool(part.width_m, t.fixed_jaw_gap_m)
        tip = self.spec.fingertip_below_tool_m
        self.grasp_z = max(job.surface_z_m + part.height_m / 2, job.surface_z_m + tip + 0.004)
        self.grasp_z = min(self.grasp_z, job.surface_z_m + part.height_m + tip - 0.010)
        self.tool_above_bottom_m = self.grasp_z - job.surface_z_m
        self.velocity = np.asarray(job.surface_velocity, float)
        width = part.width_m + t.pregrasp_clearance_m
        self.pregrasp_opening = min(1.0, self.spec.opening_for_width(width))
        self.part_height = part.height_m
        self._send_gripper(self.pregrasp_opening, None)
        self._plan_approach(obs, part)

    def _begin_segment(self, segment: JointSegment, phase: Phase, time_s: float) -> None:
        """Enter a free move; with grants required, ask for it first and hold still until answered."""
        self.segment = spliced(self._moving, segment, self._earliest(time_s), self.km.arm_velocity_limit)[0]
        self._enter(phase, time_s)
        self.request = None
        self._denied_since_s = None
        if self.grants_required:
            self._ask(time_s)
        else:
            self._go(time_s)

    def _go(self, start_s: float) -> None:
        """Send the free move, starting at `start_s` (or as soon as it can)."""
        seg, start_s = spliced(self._moving, self.segment, self._earliest(start_s), self.km.arm_velocity_limit)
        self.segment = self._moving = JointSegment(seg.q_start, seg.q_end, start_s, seg.duration_s)
        self._send_move(seg.q_end, seg.duration_s, start_s)
        if self.phase == Phase.HOME:
            self._send_gripper(1.0, start_s)
        self.phase_t0 = start_s
        self.q_cmd, self.plan_end_s = seg.q_end.copy(), start_s + seg.duration_s

    def _head_home(self, time_s: float) -> None:
        """The free move home from where the arm was last sent, at the approach's speed."""
        home = np.asarray(self.spec.home_q, float)
        segment = self.geometry.segment(self.q_cmd, home, time_s, self.timing.approach_speed)
        self._begin_segment(segment, Phase.HOME, time_s)

    # --- motion grants --------------------------------------------------------------

    def _at_home(self, q: np.ndarray) -> bool:
        return bool(
            np.max(np.abs(np.asarray(q, float) - np.asarray(self.spec.home_q, float))) <= self.timing.home_tolerance_rad
        )

    def reject(self, reason: str) -> None:
        """Refuse a task before starting it (the part is unknown): the skill ends failed with `reason`."""
        self._fail(FailureCode.REJECTED, reason)

    def cancel(self, reason: str) -> None:
        """Stop the current task; the arm finishes the goal it is on and holds there with the claw as it is (a task
        waiting out a hold is dropped: nothing is planned again on release)."""
        self.stopped_in = None
        self._fail(FailureCode.CANCELLED, reason)

    def _enter(self, phase: Phase, time_s: float) -> None:
        self.phase, self.phase_t0 = phase, time_s

    def _fail(self, code: FailureCode, reason: str) -> None:
        self.phase, self.failure = Phase.FAILED, Failure(code, reason)
        self.request = None
        self._timeline = []

    @property
    def failure_reason(self) -> str:
        """The sentence of the last failure ("" when none)."""
        return self.failure.reason if self.failure else ""

    @property
    def failure_code(self) -> str:
        """The code of the last failure ("" when none), as the bus carries it."""
        return self.failure.code.value if self.failure else ""

    @property
    def progress(self) -> float:
        """Fraction of the primitives done, for status reports."""
        if self.phase == Phase.DONE:
            return 1.0
        phase = Phase.TRANSFER if self.phase == Phase.STANDBY else self.phase
        return ORDER.index(phase) / len(ORDER) if phase in ORDER else 0.0

    @property
    def active(self) -> bool:
        return self.phase not in (Phase.IDLE, Phase.DONE, Phase.FAILED)

    @property
    def available(self) -> bool:
        """Free to start a task: idle, or on the way home (given up for the next task's approach, which the
        tracker splices in where the way home has got to)."""
        return not self.active or self.phase == Phase.HOME

    def _gripper_opening(self, obs: ArmObservation) -> float:
        c, o = self.spec.gripper_closed[0], self.spec.gripper_open[0]
        return float((np.mean(obs.gripper_q) - c) / (o - c))

    # --- each decision --------------------------------------------------------------
    def step(self, obs: ArmObservation, parts: dict[int, PartObservation]) -> list[ArmGoal]:
        """One decision at `obs.time_s`: the goals to send now (often none: the tracker is following the plan)."""
        if self.active:
            self._decide(obs, parts)
        else:
            self._clear_the_way(obs)
        return self.outbox.take(obs.time_s, watched=obs.goal_id is not None)

    def _decide(self, obs: ArmObservation, parts: dict[int, PartObservation]) -> None:
        now = self._now = obs.time_s
        if self._waiting_out_estop(obs, parts) or self._estop_ended(obs):
            return
        if obs.result_goal_id in self.sent_goals and obs.result_status in FAILED_STATUSES:
            refused = self.phase == Phase.APPROACH and obs.result_status == "rejected"  # nothing touched: no attempt
            self._fail(
                FailureCode.MOTION_DENIED if refused else FailureCode.GOAL_FAILED,
                f"trajectory goal {obs.result_goal_id} {obs.result_status}: {obs.result_reason}",
            )
            return
        if not self._resend_lost(obs):
            return
        while self._timeline and self._timeline[0][0] <= now + 1e-9:
            self._enter(self._timeline[0][1], self._timeline[0][0])
            self._timeline.pop(0)
        part = parts.get(self.job.part_id) if self.job is not None else None
        if self.request is not None:  # holding for a grant
            if self.phase == Phase.APPROACH and part is not None and now - self.request.asked_at_s > REPLAN_AFTER_S:
                self._plan_approach(obs, part)  # the part moved on: a fresh plan, asked for again
            return
        if self._timeline:
            return
        ahead = self.plan_end_s - now  # how long the planned motion still runs
        horizon = self.decision_period_s + self.latency_s + 1e-9  # the next decision's goals would come too late
        if self._detour_to is not None:  # home reached on a detour: the transfer again, from there
            if ahead <= 1e-9:
                q_to, self._detour_to = self._detour_to, None
                self._transfer(q_to, now)
            return
        if self.phase == Phase.STANDBY and ahead <= 1e-9:
            self._transfer_from_here(now)
        elif self.phase == Phase.APPROACH and ahead <= horizon:
            self._plan_grasp(part, now)
        elif self.phase == Phase.TRANSFER and ahead <= horizon:
            self._plan_place()
        elif ahead <= 1e-9:
            if self.phase == Phase.LIFT:
                self._after_lift(obs)
            elif self.phase == Phase.RETREAT:
                self._head_home(now)
            elif self.phase == Phase.HOME:
                self.phase = Phase.DONE
