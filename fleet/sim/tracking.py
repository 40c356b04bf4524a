"""Every arm of a world under its tracker (`robots.tracker`): goals in, drive targets each tick, results out.

The one way joint trajectories reach the physics: the sim server, `fleet trials` and the
PettingZoo env's allocate mode all drive their arms through this class.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable

import numpy as np

from coordinator.claw_sweep import ClawSpan
from coordinator.geometry import ArmGeometry
from fleet.sim.observe import arm_observation
from fleet.sim.outside_hold import OutsideHold, OutsideHoldState
from fleet.sim.safety import PlantSafety, Refusal, SafetyState
from fleet.sim.world import World
from robots.frames import yaw_transform
from robots.joint_trajectory import OUTSIDE_REASON, ArmGoal, GoalResult, GoalStatus, GripperGoal, ResultCode
from robots.saved_state import SavedState
from robots.skills.interface import PartObservation
from robots.skills.pick_place import PickPlaceSkill
from robots.tracker import ArmTracker
from robots.tracker_state import TrackerState, restore_tracker, tracker_state


@dataclasses.dataclass(frozen=True)
class GripperOpening:
    """How open a gripper is (0 closed, 1 open) from its joints: the mean of each joint's way from closed to open.
    A class, not a closure, so a tracker holding it is part of a run's snapshot."""

    closed: np.ndarray
    span: np.ndarray

    def __call__(self, gripper_q: np.ndarray) -> float:
        return float(np.mean((gripper_q - self.closed) / self.span))


class TrackedState(SavedState, frozen=True):
    """What `TrackedArms` saves: every tracker, the arms outside clients hold, the safety layer's counts and what
    was last written to each arm's drives (so a restored line writes exactly what the saved one would)."""

    trackers: dict[str, TrackerState]
    outside: OutsideHoldState
    safety: SafetyState
    effort_n: dict[str, float]  # the gripper effort last set on each arm
    opening: dict[str, float]  # the claw opening last turned into gripper targets
    gripper_q: dict[str, tuple[float, ...]]  # those targets
    holding: dict[str, bool]  # whether the arm's drives hold its tracker's hold point as last written


class TrackedArms:
    """Trackers by arm id over a world; call `apply()` before each tick's physics and `update()` after it."""

    def __init__(self, world: World) -> None:
        self.world = world
        self.trackers: dict[str, ArmTracker] = {}
        for name, arm in world.arms.items():
            spec, n = arm.spec, arm.spec.arm_dof
            lower, upper = arm.joint_limits()
            c, o = np.asarray(spec.gripper_closed, float), np.asarray(spec.gripper_open, float)
            span = np.where(np.abs(o - c) > 1e-12, o - c, 1.0)
            self.trackers[name] = ArmTracker(
                tuple(spec.arm_joints),
                lower[:n],
                upper[:n],
                arm.qpos()[:n],
                opening_of=GripperOpening(c, span),
                default_effort_n=spec.gripper_gains.force_limit,
                servo_period_s=world.control_dt_s,
            )
        self._effort = {name: t.claw.effort_n for name, t in self.trackers.items()}
        self._opening: dict[str, float] = {}
        self._held: dict[str, np.ndarray | None] = {}  # the hold point last written, per arm holding still
        self._gripper_q: dict[str, tuple[float, ...]] = {}
        self.safety = plant_safety(world)
        self.outside = OutsideHold()  # the arms outside clients drive (see `submit`)

    def use_world(self, world: World) -> None:
        """Drive `world`, a world of the same scene built afresh (after a snapshot); its state is put in after."""
        self.world = world

    def state(self) -> TrackedState:
        return TrackedState(
            trackers={name: tracker_state(t) for name, t in self.trackers.items()},
            outside=self.outside.state(),
            safety=self.safety.state(),
            effort_n=dict(self._effort),
            opening=dict(self._opening),
            gripper_q=dict(self._gripper_q),
            holding={name: q is not None and q is self.trackers[name].hold_q for name, q in self._held.items()},
        )

    def restore(self, state: TrackedState) -> None:
        """Put a saved state back (trackers of the same arms, over this world)."""
        for name, t in state.trackers.items():
            restore_tracker(self.trackers[name], t)
        self.outside.restore(state.outside)
        self.safety.restore(state.safety)
        self._effort, self._opening = dict(state.effort_n), dict(state.opening)
        self._gripper_q = {name: tuple(q) for name, q in state.gripper_q.items()}
        self._held = {name: self.trackers[name].hold_q if held else None for name, held in state.holding.items()}

    def submit(self, arm: str, goal: ArmGoal, outside: bool = False) -> list[GoalResult]:
        """Hand `arm`'s tracker a goal now, through the plant's safety layer; the refusal or the preempted goals'
        results come back. An accepted `outside` goal (a client that is not the arm's controller: ROS) takes the
        arm (`OutsideHold`): its controller's goals are refused until the client lets go, and those it sent
        before are cancelled at the take."""
        tracker, now = self.trackers[arm], self.world.sim_time_s
        if not outside and self.taken(arm):
            until = self.outside.let_go_at(arm)
            why = OUTSIDE_REASON + (f" until {until:.2f} s" if math.isfinite(until) else "")
            if isinstance(goal, GripperGoal):
                return [GoalResult(goal.goal_id, "gripper", GoalStatus.REJECTED, ResultCode.INVALID_GOAL, why, now)]
            return tracker.refuse(goal, why, now)
        results = self._submit_checked(arm, goal)
        refused = any(r.goal_id == goal.goal_id and r.status == GoalStatus.REJECTED for r in results)
        if not outside or refused:
            return results
        if self.outside.take(arm, goal.goal_id):
            results += self._cancel_for_outside(arm, goal)
        return [dataclasses.replace(r, reason=f"{OUTSIDE_REASON}: {r.reason}") for r in results]

    def _submit_checked(self, arm: str, goal: ArmGoal) -> list[GoalResult]:
        """A goal through the plant's safety layer to the tracker: the refusal or the preempted goals' results."""
        tracker, now = self.trackers[arm], self.world.sim_time_s
        if isinstance(goal, GripperGoal):
            refusal = self._claw_refusal(arm, goal)
            if refusal is not None:
                why = f"safety: {refusal.reason}"
                return [GoalResult(goal.goal_id, "gripper", GoalStatus.REJECTED, ResultCode.INVALID_GOAL, why, now)]
            return tracker.submit(goal, now)
        planned = tracker.plan(goal, now)
        if isinstance(planned, list):
            return planned
        refusal = self.safety.refusal(arm, planned.spline, self.trackers, self.claws())
        if refusal is not None:
            return tracker.refuse(goal, f"safety: {refusal.reason}", now)
        return tracker.commit(planned, now)

    def _cancel_for_outside(self, arm: str, goal: ArmGoal) -> list[GoalResult]:
        """At the take: the controller's goals that would still move the arm end (its claw goal waiting to start;
        with a claw goal, its path too: the arm holds where it is)."""
        tracker, now, why = self.trackers[arm], self.world.sim_time_s, "cancelled: an outside client took the arm"
        out = []
        waiting = tracker.claw.waiting
        if not (waiting is not None and waiting.goal.goal_id == goal.goal_id):
            out += tracker.claw.cancel_waiting(now, why)
        if isinstance(goal, GripperGoal):
            out += tracker.stop_path(now, self._arm_q(arm), why)
        return out

    def _claw_refusal(self, arm: str, goal: GripperGoal) -> Refusal | None:
        """The safety layer's refusal of a claw goal (None where it may run, or where the tracker refuses it
        itself: an e-stop, an opening out of range)."""
        tracker = self.trackers[arm]
        if tracker.estop or not (math.isfinite(goal.opening) and 0.0 <= goal.opening <= 1.0):
            return None
        return self.safety.claw_refusal(arm, goal.opening, self.world.sim_time_s, self.trackers, self.claws())

    def claw_span(self, arm: str) -> ClawSpan:
        """The openings `arm`'s claw may take until its next claw goal: where it is, where its goal takes it and
        where a pending goal will."""
        tracker, a = self.trackers[arm], self.world.arms[arm]
        claw = tracker.claw
        span = ClawSpan.at(claw.opening_of(a.qpos()[a.spec.arm_dof :])).union(claw.opening)
        return span if claw.waiting is None else span.union(claw.waiting.goal.opening)

    def claws(self) -> Callable[[str], ClawSpan]:
        """Each arm's `claw_span` now, read once per arm however often it is asked."""
        return functools.cache(self.claw_span)

    def taken(self, arm: str) -> bool:
        """Whether an outside client drives `arm` now (its controller waits, the coordinator gives it nothing)."""
        return self.outside.taken(arm, self.trackers[arm], self.world.sim_time_s)

    def decide(self, arm: str, skill: PickPlaceSkill, parts: dict[int, PartObservation]) -> None:
        """One decision of `arm`'s skill in process, as a controller makes it over the bus: it sees the arm (with its
        tracker's newest result) and the parts, and its goals go to the arm's tracker."""
        for goal in skill.step(arm_observation(self.world, arm, self.trackers[arm]), parts):
            self.submit(arm, goal)

    def apply(self) -> None:
        """Drive targets for this tick from every tracker (its trajectory, or where it holds)."""
        now = self.world.sim_time_s
        for name, tracker in self.trackers.items():
            arm = self.world.arms[name]
            holding = tracker.idle
            if holding and self._held.get(name) is tracker.hold_q:
                continue  # holding where it held last tick: the drives already have these targets
            self._held[name] = tracker.hold_q if holding else None
            q, dq = tracker.desired(now)
            if tracker.claw.effort_n != self._effort[name]:
                arm.set_gripper_effort(tracker.claw.effort_n)
                self._effort[name] = tracker.claw.effort_n
            opening = tracker.gripper_opening()
            if opening != self._opening.get(name):
                self._gripper_q[name], self._opening[name] = arm.spec.gripper_targets(opening), opening
            arm.set_targets(q, dq, self._gripper_q[name])

    def update(self) -> dict[str, list[GoalResult]]:
        """After the tick's physics: each arm's finished goals (tolerances, ends, watchdog)."""
        now, out = self.world.sim_time_s, {}
        for name, tracker in self.trackers.items():
            if tracker.idle and now <= tracker.watchdog_deadline_s:
                continue  # nothing to check: no joints to read
            arm = self.world.arms[name]
            q, dq, n = arm.qpos(), arm.qvel(), arm.spec.arm_dof
            results = tracker.update(now, q[:n], q[n:], dq[n:])
            if results:
                out[name] = results
        for name in self.safety.too_close(now, self._arm_q, self.trackers, self.claws()):
            out.setdefault(name, []).extend(
                self.abort(name, "safety stop: within the plant's separation of another arm")
            )
        return out

    def _arm_q(self, name: str) -> np.ndarray:
        arm = self.world.arms[name]
        return arm.qpos()[: arm.spec.arm_dof]

    def abort(self, arm: str, reason: str) -> list[GoalResult]:
        """Stop `arm` where it is now, aborting its goals with `reason`."""
        a = self.world.arms[arm]
        return self.trackers[arm].abort(self.world.sim_time_s, a.qpos()[: a.spec.arm_dof], reason)

    def set_estop(self, engaged: bool) -> dict[str, list[GoalResult]]:
        """Engage or release the e-stop on every arm; engaging aborts every goal and holds every arm."""
        out = {}
        for name, tracker in self.trackers.items():
            a = self.world.arms[name]
            results = tracker.set_estop(engaged, self.world.sim_time_s, a.qpos()[: a.spec.arm_dof])
            if results:
                out[name] = results
        return out


def plant_safety(world: World) -> PlantSafety:
    """The safety layer over a world's arms: their collision shapes where the scene puts them, the scene's
    separation, each robot's joint velocity limits."""
    geometries, limits = {}, {}
    for a in world.scene_model.arms:
        spec = world.arms[a.name].spec
        g = ArmGeometry(a.name, spec, yaw_transform(a.base.xyz, a.base.yaw_rad))
        geometries[a.name] = g
        limits[a.name] = g.km.arm_velocity_limit
    return PlantSafety(geometries, world.scene_model.safety_separation_m, limits)
