"""Pick a part (from a moving conveyor or a still surface) and place it: the bridge layer's skill.

Primitives, in order: approach above the part's predicted position, descend
while tracking it, close, lift, transfer, lower, release, retreat. The grasp
is a friction grasp made by the physics: this code only moves the joints and
commands the gripper opening. It sees the world only through
`ArmObservation` / `PartObservation` and answers an `ArmCommand`.

With `grants_required`, each free joint-space move (approach, transfer, home) is first
asked for: the skill holds still with a `MotionRequest` out until `on_grant` answers. A
denied approach ends the task failed (the coordinator may give it again); a denied
transfer or return home, with a part in the claw or none, is asked for again. An approach
kept waiting past `REPLAN_AFTER_S` is planned again from where the part is by then.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from robots.frames import rotation_from_wxyz, wrap_angle
from robots.kinematics import KinematicModel
from robots.skills.interface import ArmCommand, ArmObservation, PartObservation, PickPlaceTask
from robots.spec import RobotSpec
from robots.top_down import TopDownIK
from robots.trajectory import JointSegment, quintic


class Phase(str, Enum):
    IDLE = "idle"
    APPROACH = "approach"
    DESCEND = "descend"
    CLOSE = "close"
    LIFT = "lift"
    TRANSFER = "transfer"
    LOWER = "lower"
    RELEASE = "release"
    RETREAT = "retreat"
    HOME = "home"
    DONE = "done"
    FAILED = "failed"


SEGMENT_PHASES = (Phase.APPROACH, Phase.TRANSFER, Phase.HOME)  # free joint-space moves: the ones that need a grant
REPLAN_AFTER_S = 0.3
ORDER = [Phase.APPROACH, Phase.DESCEND, Phase.CLOSE, Phase.LIFT, Phase.TRANSFER, Phase.LOWER, Phase.RELEASE, Phase.RETREAT, Phase.HOME]


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
    approach_speed: float = 0.6
    transfer_speed: float = 0.45
    pregrasp_clearance_m: float = 0.024
    place_drop_m: float = 0.008


@dataclass(frozen=True)
class MotionRequest:
    """A joint-space move the skill wants to make: from `q_from` to `q_to` in `duration_s`, asked at `asked_at_s`."""

    seq: int
    q_from: tuple[float, ...]
    q_to: tuple[float, ...]
    duration_s: float
    asked_at_s: float


class PickPlaceSkill:
    """State machine for one pick-and-place; call `start`, then `step` once per control tick."""

    def __init__(
        self,
        spec: RobotSpec,
        transform_base_to_world: np.ndarray,
        *,
        timing: PickPlaceTiming = PickPlaceTiming(),
        model: KinematicModel | None = None,
        grants_required: bool = False,
    ) -> None:
        self.spec, self.timing = spec, timing
        self.grants_required = grants_required
        self.request: MotionRequest | None = None
        self._request_seq = 0
        self.denials = 0
        self.km = model or KinematicModel(spec)
        self.top_down = TopDownIK(spec, transform_base_to_world, self.km)
        self.phase = Phase.IDLE
        self.failure_reason = ""
        self.task: PickPlaceTask | None = None
        self.ik_failures = 0

    # --- geometry -------------------------------------------------------------------
    def _ik(self, position_world: np.ndarray, yaw_world: float, q_start: np.ndarray) -> tuple[np.ndarray, bool]:
        return self.top_down.solve(position_world, yaw_world, q_start)

    def _natural_yaw(self, position_world: np.ndarray) -> float:
        return self.top_down.natural_yaw(position_world)

    def _grasp_yaw(self, part: PartObservation) -> float:
        """A yaw that closes the fingers across the part's narrow side, nearest the natural yaw."""
        natural = self._natural_yaw(part.position)
        if part.size_m is None:
            return natural
        sx, sy, _ = part.size_m
        axes = rotation_from_wxyz(part.quaternion_wxyz)
        across = axes[:, 0] if sx <= sy else axes[:, 1]
        base = math.atan2(across[0], -across[1])  # tool y = (sin yaw, -cos yaw) along `across`
        step = math.pi / 2 if abs(sx - sy) < 1e-6 else math.pi
        candidates = [wrap_angle(base + k * step) for k in range(int(round(2 * math.pi / step)))]
        return min(candidates, key=lambda c: abs(wrap_angle(c - natural)))

    # --- the state machine ----------------------------------------------------------
    def start(self, task: PickPlaceTask, obs: ArmObservation, part: PartObservation) -> None:
        """Begin a pick of `part`; fails at once, with a reason, if the part cannot be reached."""
        t = self.timing
        self.task, self.failure_reason = task, ""
        self.q_cmd = np.asarray(obs.q, float).copy()
        self.grasp_yaw = self._grasp_yaw(part)
        tip = self.spec.fingertip_below_tool_m
        self.grasp_z = max(task.surface_z_m + part.height_m / 2, task.surface_z_m + tip + 0.004)
        self.grasp_z = min(self.grasp_z, task.surface_z_m + part.height_m + tip - 0.010)
        self.tool_above_bottom_m = self.grasp_z - task.surface_z_m
        self.velocity = np.asarray(task.surface_velocity, float)
        width = part.width_m + t.pregrasp_clearance_m
        self.pregrasp_opening = min(1.0, self.spec.opening_for_width(width))
        self.part_height = part.height_m
        self._plan_approach(obs, part)

    def _plan_approach(self, obs: ArmObservation, part: PartObservation) -> None:
        """The move above where the part will be when the claw gets there (two passes refine the travel time)."""
        t = self.timing
        lead = t.descend_s
        seg = None
        for _ in range(2):
            hover = part.position + self.velocity * lead
            hover = np.array([hover[0], hover[1], self.grasp_z + t.hover_m])
            q_hover, ok = self._ik(hover, self.grasp_yaw, self.q_cmd)
            if not ok:
                self._fail(f"part {part.part_id} cannot be reached from above at {np.round(hover, 3).tolist()}")
                return
            seg = JointSegment.timed(self.q_cmd, q_hover, obs.time_s, self.km.velocity_limit[self.km.arm_q_index], t.approach_speed)
            lead = seg.duration_s + t.descend_s * 0.5
        self._begin_segment(seg, Phase.APPROACH, obs.time_s)

    # --- motion grants --------------------------------------------------------------
    def _begin_segment(self, segment: JointSegment, phase: Phase, time_s: float) -> None:
        """Enter a free move; with grants required, ask for it first and hold still until answered."""
        self.segment = segment
        self._enter(phase, time_s)
        self.request = None
        if self.grants_required:
            self._ask(time_s)

    def _ask(self, time_s: float) -> None:
        self._request_seq += 1
        seg = self.segment
        self.request = MotionRequest(
            self._request_seq, tuple(map(float, self.q_cmd)), tuple(map(float, seg.q_end)), float(seg.duration_s), time_s,
        )

    def on_grant(self, request_seq: int, decision: str, conflict_arm: str, time_s: float) -> None:
        """The coordinator's answer to request `request_seq` (stale answers are ignored): grant, or deny naming the arm."""
        if self.request is None or request_seq != self.request.seq or not self.active:
            return
        if decision == "grant":
            self.segment = dataclasses.replace(self.segment, t0_s=time_s)  # the arm held still: the planned move, from now
            self.phase_t0 = time_s
            self.request = None
            return
        self.denials += 1
        if self.phase == Phase.APPROACH:  # nothing in hand: give the task back, the coordinator decides again
            self.request = None
            self._fail(f"motion denied: the approach would pass within the margin of {conflict_arm or 'another arm'}")
        else:  # a part in the claw, or on the way home: ask again
            self._ask(time_s)

    def _waiting(self, obs: ArmObservation, part: PartObservation | None, opening: float) -> ArmCommand | None:
        """While a request is out: hold still (re-planning a long-kept approach). None once free to move."""
        if self.request is None:
            return None
        if self.phase == Phase.APPROACH and part is not None and obs.time_s - self.request.asked_at_s > REPLAN_AFTER_S:
            self._plan_approach(obs, part)  # the part moved on: a fresh plan, asked for again
        return ArmCommand(self.q_cmd, np.zeros_like(self.q_cmd), opening)

    def reject(self, reason: str) -> None:
        """Refuse a task before starting it (the part is unknown): the skill ends failed with `reason`."""
        self._fail(reason)

    def cancel(self, reason: str) -> None:
        """Stop the current task where the arm is; it holds its last target with the claw as it is."""
        self._fail(reason)

    def _enter(self, phase: Phase, time_s: float) -> None:
        self.phase, self.phase_t0 = phase, time_s

    def _fail(self, reason: str) -> None:
        self.phase, self.failure_reason = Phase.FAILED, reason
        self.request = None

    @property
    def progress(self) -> float:
        """Fraction of the primitives done, for status reports."""
        if self.phase == Phase.DONE:
            return 1.0
        return ORDER.index(self.phase) / len(ORDER) if self.phase in ORDER else 0.0

    @property
    def active(self) -> bool:
        return self.phase not in (Phase.IDLE, Phase.DONE, Phase.FAILED)

    def _gripper_opening(self, obs: ArmObservation) -> float:
        c, o = self.spec.gripper_closed[0], self.spec.gripper_open[0]
        return float((np.mean(obs.gripper_q) - c) / (o - c))

    def _track(self, position_world: np.ndarray, yaw: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
        q, ok = self._ik(position_world, yaw, self.q_cmd)
        if not ok:
            self.ik_failures += 1
        dq = (q - self.q_cmd) / dt if dt > 0 else np.zeros_like(q)
        self.q_cmd = q
        return q, dq

    def step(self, obs: ArmObservation, parts: dict[int, PartObservation], dt: float) -> ArmCommand:
        """One control tick: the joint targets and gripper opening for now."""
        t, now = self.timing, obs.time_s
        elapsed = now - getattr(self, "phase_t0", now)
        if not self.active:
            return ArmCommand(self.q_cmd if hasattr(self, "q_cmd") else obs.q, np.zeros_like(obs.q), 1.0)
        part = parts.get(self.task.part_id)
        if self.phase in SEGMENT_PHASES:
            opening = {Phase.APPROACH: self.pregrasp_opening, Phase.TRANSFER: 0.0, Phase.HOME: 1.0}[self.phase]
            held = self._waiting(obs, part, opening)
            if held is not None:
                return held
        if self.phase == Phase.APPROACH:
            q, dq = self.segment.sample(now)
            self.q_cmd = q
            if self.segment.done(now):
                self._enter(Phase.DESCEND, now)
            return ArmCommand(q, dq, self.pregrasp_opening)
        if self.phase in (Phase.DESCEND, Phase.CLOSE):
            if part is None:
                self._fail(f"part {self.task.part_id} vanished before the grasp")
                return ArmCommand(self.q_cmd, np.zeros_like(self.q_cmd), 1.0)
            aim = part.position + self.velocity * t.track_lead_s
            if self.phase == Phase.DESCEND:
                z = self.grasp_z + t.hover_m * (1 - quintic(elapsed / t.descend_s))
                opening = self.pregrasp_opening
                if elapsed >= t.descend_s:
                    self._enter(Phase.CLOSE, now)
            else:
                z, opening = self.grasp_z, 0.0
                if elapsed >= t.close_s:
                    self.lift_xy = np.array([aim[0], aim[1]])
                    self._enter(Phase.LIFT, now)
            q, dq = self._track(np.array([aim[0], aim[1], z]), self.grasp_yaw, dt)
            return ArmCommand(q, dq, opening)
        if self.phase == Phase.LIFT:
            xy = self.lift_xy + self.velocity[:2] * min(elapsed, 0.15)
            z = self.grasp_z + t.lift_m * quintic(elapsed / t.lift_s)
            q, dq = self._track(np.array([xy[0], xy[1], z]), self.grasp_yaw, dt)
            if elapsed >= t.lift_s:
                if self._gripper_opening(obs) < 0.03:
                    self._fail(f"grasp of part {self.task.part_id} missed: the claw closed on nothing")
                    return ArmCommand(q, np.zeros_like(q), 1.0)
                place = np.asarray(self.task.place_xyz, float)
                self.place_yaw = self._natural_yaw(place)
                above = place + [0, 0, self.tool_above_bottom_m + t.hover_m]
                q_above, ok = self._ik(above, self.place_yaw, self.q_cmd)
                if not ok:
                    self._fail(f"place position {np.round(place, 3).tolist()} cannot be reached")
                    return ArmCommand(q, np.zeros_like(q), 0.0)
                self._begin_segment(
                    JointSegment.timed(q, q_above, now, self.km.velocity_limit[self.km.arm_q_index], t.transfer_speed), Phase.TRANSFER, now,
                )
            return ArmCommand(q, dq, 0.0)
        if self.phase == Phase.TRANSFER:
            q, dq = self.segment.sample(now)
            self.q_cmd = q
            if self.segment.done(now):
                self._enter(Phase.LOWER, now)
            return ArmCommand(q, dq, 0.0)
        place = np.asarray(self.task.place_xyz, float)
        release_z = place[2] + self.tool_above_bottom_m + t.place_drop_m
        if self.phase == Phase.LOWER:
            z = release_z + t.hover_m * (1 - quintic(elapsed / t.lower_s))
            q, dq = self._track(np.array([place[0], place[1], z]), self.place_yaw, dt)
            if elapsed >= t.lower_s:
                self._enter(Phase.RELEASE, now)
            return ArmCommand(q, dq, 0.0)
        if self.phase == Phase.RELEASE:
            if elapsed >= t.release_s:
                self._enter(Phase.RETREAT, now)
            return ArmCommand(self.q_cmd, np.zeros_like(self.q_cmd), self.pregrasp_opening)
        if self.phase == Phase.RETREAT:
            z = release_z + t.hover_m * quintic(elapsed / t.retreat_s)
            q, dq = self._track(np.array([place[0], place[1], z]), self.place_yaw, dt)
            if elapsed >= t.retreat_s:
                home = np.asarray(self.spec.home_q, float)
                self._begin_segment(
                    JointSegment.timed(q, home, now, self.km.velocity_limit[self.km.arm_q_index], t.approach_speed), Phase.HOME, now,
                )
            return ArmCommand(q, dq, self.pregrasp_opening)
        # HOME
        q, dq = self.segment.sample(now)
        self.q_cmd = q
        if self.segment.done(now):
            self.phase = Phase.DONE
        return ArmCommand(q, dq, 1.0)
