"""What a pick-and-place skill saves: its task, plan, motion requests and counts; not what it was built with (the
robot, its kinematics, its timing), which a skill built for the same arm has already."""

from __future__ import annotations

import numpy as np

from robots.failures import Failure
from robots.phase import Phase
from robots.saved_state import SavedState
from robots.skills.goal_outbox import OutboxState
from robots.skills.interface import MotionRequest, PickPlaceJob
from robots.skills.pick_place import PickPlaceSkill
from robots.trajectory import JointSegment


class SkillState(SavedState, frozen=True):
    """A `PickPlaceSkill`'s state (`skill_state` and `restore_skill`)."""

    now_s: float
    latency_s: float
    decision_period_s: float
    phase: Phase
    phase_t0: float
    failure: Failure | None
    job: PickPlaceJob | None
    grasp_yaw: float  # the grasp worked out when the task started
    grasp_z: float
    tool_above_bottom_m: float
    velocity: np.ndarray
    pregrasp_opening: float
    part_height: float
    q_cmd: np.ndarray | None  # the joints last commanded (None until the first task)
    segment: JointSegment | None  # the free move asked for or sent last
    moving: JointSegment | None  # the free move sent last
    timeline: list[tuple[float, Phase]]
    plan_end_s: float
    request: MotionRequest | None
    request_seq: int
    then_cached: tuple[Phase, tuple[float, ...]] | None  # the move whose local stage after it was worked out last
    then_after_s: list[float]
    then_q: list[np.ndarray]
    stopped_in: Phase | None
    idle_since_s: float | None
    denied_since_s: float | None
    detour_to: np.ndarray | None
    stood_by: bool
    transfer_to: np.ndarray | None
    missed_yaws: dict[int, list[float]]
    place_yaw: float
    pick_tilt_rad: float
    place_tilt_rad: float
    grasp_centre: tuple[float, float, float]
    grasp_world: np.ndarray
    pick_up: np.ndarray
    place_up: np.ndarray
    outbox: OutboxState
    denials: int
    ik_failures: int
    standbys: int
    detours: int
    estops: int


def skill_state(skill: PickPlaceSkill) -> SkillState:
    """What `skill` saves."""
    plan, plans, grants = skill.plan, skill.plans, skill.grants
    then_key, (then_after_s, then_q) = grants.then_cache
    return SkillState(
        now_s=plan.now_s,
        latency_s=plan.latency_s,
        decision_period_s=plan.decision_period_s,
        phase=plan.phase,
        phase_t0=plan.phase_t0,
        failure=plan.failure,
        job=plan.job,
        grasp_yaw=plans.grasp_yaw,
        grasp_z=plans.grasp_z,
        tool_above_bottom_m=plans.tool_above_bottom_m,
        velocity=plans.velocity,
        pregrasp_opening=plans.pregrasp_opening,
        part_height=plans.part_height,
        q_cmd=plan.q_cmd,
        segment=plan.segment,
        moving=plan.moving,
        timeline=list(plan.timeline),
        plan_end_s=plan.plan_end_s,
        request=plan.request,
        request_seq=grants.request_seq,
        then_cached=then_key,
        then_after_s=list(then_after_s),
        then_q=list(then_q),
        stopped_in=skill.estop.stopped_in,
        idle_since_s=skill.recovery.idle_since_s,
        denied_since_s=grants.denied_since_s,
        detour_to=grants.detour_to,
        stood_by=grants.stood_by,
        transfer_to=grants.transfer_to,
        missed_yaws=plans.missed_yaws,
        place_yaw=plans.place_yaw,
        pick_tilt_rad=plans.pick_tilt_rad,
        place_tilt_rad=plans.place_tilt_rad,
        grasp_centre=tuple(plans.grasp_centre),
        grasp_world=plans.grasp_world,
        pick_up=plans.pick_up,
        place_up=plans.place_up,
        outbox=skill.outbox.state(),
        denials=grants.denials,
        ik_failures=plans.ik_failures,
        standbys=grants.standbys,
        detours=grants.detours,
        estops=skill.estop.estops,
    )


def restore_skill(skill: PickPlaceSkill, s: SkillState) -> None:
    """Put `s` back into `skill`, a skill built for the same arm."""
    plan, plans, grants = skill.plan, skill.plans, skill.grants
    plan.now_s, plan.latency_s, plan.decision_period_s = s.now_s, s.latency_s, s.decision_period_s
    plan.phase, plan.phase_t0, plan.failure, plan.job = s.phase, s.phase_t0, s.failure, s.job
    plan.q_cmd, plan.segment, plan.moving = s.q_cmd, s.segment, s.moving
    plan.timeline, plan.plan_end_s, plan.request = list(s.timeline), s.plan_end_s, s.request
    plans.grasp_yaw, plans.grasp_z, plans.velocity = s.grasp_yaw, s.grasp_z, s.velocity
    plans.tool_above_bottom_m, plans.part_height = s.tool_above_bottom_m, s.part_height
    plans.pregrasp_opening, plans.ik_failures = s.pregrasp_opening, s.ik_failures
    plans.missed_yaws = {k: list(v) for k, v in s.missed_yaws.items()}
    plans.place_yaw, plans.pick_tilt_rad, plans.place_tilt_rad = s.place_yaw, s.pick_tilt_rad, s.place_tilt_rad
    plans.grasp_centre, plans.grasp_world = s.grasp_centre, s.grasp_world
    plans.pick_up, plans.place_up = s.pick_up, s.place_up
    grants.request_seq, grants.then_cache = s.request_seq, (s.then_cached, (list(s.then_after_s), list(s.then_q)))
    grants.denied_since_s, grants.detour_to = s.denied_since_s, s.detour_to
    grants.stood_by, grants.transfer_to = s.stood_by, s.transfer_to
    grants.denials, grants.standbys, grants.detours = s.denials, s.standbys, s.detours
    skill.estop.stopped_in, skill.estop.estops = s.stopped_in, s.estops
    skill.recovery.idle_since_s = s.idle_since_s
    skill.outbox.restore(s.outbox)
