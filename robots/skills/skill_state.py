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
    then_key, (then_after_s, then_q) = skill._then_cache
    return SkillState(
        now_s=skill._now,
        latency_s=skill.latency_s,
        decision_period_s=skill.decision_period_s,
        phase=skill.phase,
        phase_t0=skill.phase_t0,
        failure=skill.failure,
        job=skill.job,
        grasp_yaw=skill.grasp_yaw,
        grasp_z=skill.grasp_z,
        tool_above_bottom_m=skill.tool_above_bottom_m,
        velocity=skill.velocity,
        pregrasp_opening=skill.pregrasp_opening,
        part_height=skill.part_height,
        q_cmd=skill.q_cmd,
        segment=skill.segment,
        moving=skill._moving,
        timeline=list(skill._timeline),
        plan_end_s=skill.plan_end_s,
        request=skill.request,
        request_seq=skill._request_seq,
        then_cached=then_key,
        then_after_s=list(then_after_s),
        then_q=list(then_q),
        stopped_in=skill.stopped_in,
        idle_since_s=skill._idle_since_s,
        denied_since_s=skill._denied_since_s,
        detour_to=skill._detour_to,
        stood_by=skill._stood_by,
        transfer_to=skill._transfer_to,
        missed_yaws=skill.missed_yaws,
        place_yaw=skill.place_yaw,
        pick_tilt_rad=skill.pick_tilt_rad,
        place_tilt_rad=skill.place_tilt_rad,
        grasp_centre=tuple(skill.grasp_centre),
        grasp_world=skill._grasp_world,
        pick_up=skill._pick_up,
        place_up=skill._place_up,
        outbox=skill.outbox.state(),
        denials=skill.denials,
        ik_failures=skill.ik_failures,
        standbys=skill.standbys,
        detours=skill.detours,
        estops=skill.estops,
    )


def restore_skill(skill: PickPlaceSkill, s: SkillState) -> None:
    """Put `s` back into `skill`, a skill built for the same arm."""
    skill._now, skill.latency_s, skill.decision_period_s = s.now_s, s.latency_s, s.decision_period_s
    skill.phase, skill.phase_t0, skill.failure, skill.job = s.phase, s.phase_t0, s.failure, s.job
    skill.grasp_yaw, skill.grasp_z, skill.velocity = s.grasp_yaw, s.grasp_z, s.velocity
    skill.tool_above_bottom_m, skill.part_height, skill.pregrasp_opening = (
        s.tool_above_bottom_m,
        s.part_height,
        s.pregrasp_opening,
    )
    skill.q_cmd, skill.segment = s.q_cmd, s.segment
    skill._moving, skill._timeline, skill.plan_end_s = s.moving, list(s.timeline), s.plan_end_s
    skill.request, skill._request_seq = s.request, s.request_seq
    skill._then_cache = (s.then_cached, (list(s.then_after_s), list(s.then_q)))
    skill.stopped_in, skill._idle_since_s, skill._denied_since_s = s.stopped_in, s.idle_since_s, s.denied_since_s
    skill._detour_to, skill._stood_by, skill._transfer_to = s.detour_to, s.stood_by, s.transfer_to
    skill.missed_yaws = {k: list(v) for k, v in s.missed_yaws.items()}
    skill.place_yaw, skill.pick_tilt_rad, skill.place_tilt_rad = s.place_yaw, s.pick_tilt_rad, s.place_tilt_rad
    skill.grasp_centre, skill._grasp_world = s.grasp_centre, s.grasp_world
    skill._pick_up, skill._place_up = s.pick_up, s.place_up
    skill.outbox.restore(s.outbox)
    skill.denials, skill.ik_failures, skill.standbys = s.denials, s.ik_failures, s.standbys
    skill.detours, skill.estops = s.detours, s.estops
