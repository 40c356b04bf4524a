"""The goals a skill sends: numbered over the skill's whole life, queued until its decision returns them, and each
batch with a trajectory goal watched until the tracker shows it (sent again, later, when the bus lost it)."""

from __future__ import annotations

import dataclasses

import numpy as np

from robots.joint_trajectory import ArmGoal, GripperGoal, TrajectoryGoal, rest_to_rest
from robots.saved_state import SavedState
from robots.trajectory import knot_velocities

PATH_TOLERANCE_RAD = 0.3  # a joint this far off its path (blocked, knocked) aborts the goal and the task


class SavedGoal(SavedState, frozen=True):
    """One goal of a saved outbox: a trajectory goal or a gripper goal."""

    trajectory: TrajectoryGoal | None = None
    gripper: GripperGoal | None = None

    @classmethod
    def of(cls, goal: ArmGoal) -> SavedGoal:
        return cls(trajectory=goal) if isinstance(goal, TrajectoryGoal) else cls(gripper=goal)

    @property
    def goal(self) -> ArmGoal:
        return self.trajectory if self.trajectory is not None else self.gripper


class OutboxState(SavedState, frozen=True):
    """What a `GoalOutbox` saves: its count, the current task's goals, those queued and those not yet shown."""

    goal_id: int
    sent: list[int]
    queued: list[SavedGoal]
    unconfirmed: list[tuple[float, int, list[SavedGoal]]]
    resent: int


class GoalOutbox:
    """Builds and numbers one arm's goals; `take` hands the queued ones out."""

    def __init__(self, joint_names: tuple[str, ...]) -> None:
        self.joint_names = joint_names
        self.goal_id = 0  # ids of the goals sent: increasing over the skill's whole life
        self.sent: set[int] = set()  # trajectory goals of the current task
        self.queued: list[ArmGoal] = []
        # batches with a trajectory goal the tracker has not shown yet: (sent at, sends, goals)
        self.unconfirmed: list[tuple[float, int, list[ArmGoal]]] = []
        self.resent = 0

    def state(self) -> OutboxState:
        """What this outbox saves (`restore` puts it back)."""
        return OutboxState(
            goal_id=self.goal_id,
            sent=sorted(self.sent),
            queued=[SavedGoal.of(g) for g in self.queued],
            unconfirmed=[(t, n, [SavedGoal.of(g) for g in goals]) for t, n, goals in self.unconfirmed],
            resent=self.resent,
        )

    def restore(self, state: OutboxState) -> None:
        self.goal_id, self.sent, self.resent = state.goal_id, set(state.sent), state.resent
        self.queued = [g.goal for g in state.queued]
        self.unconfirmed = [(t, n, [g.goal for g in goals]) for t, n, goals in state.unconfirmed]

    def next_id(self) -> int:
        self.goal_id += 1
        return self.goal_id

    def forget(self) -> None:
        """A new task (or none): the goals of the last one are no longer watched."""
        self.sent, self.unconfirmed = set(), []

    def move(self, q_end: np.ndarray, duration_s: float, start_s: float) -> None:
        """A rest-to-rest move to `q_end` in `duration_s`, from `start_s`."""
        goal = rest_to_rest(
            self.next_id(), self.joint_names, q_end, duration_s, start_s, path_tolerance_rad=(PATH_TOLERANCE_RAD,)
        )
        self.sent.add(goal.goal_id)
        self.queued.append(goal)

    def knots(self, start_s: float, times_s: np.ndarray, qs: np.ndarray) -> None:
        """A goal through joint knots at `start_s + times_s`, with velocities from the knots (cubic between them)."""
        dq = knot_velocities(times_s, qs)  # every stage ends at rest
        goal = TrajectoryGoal(
            self.next_id(),
            self.joint_names,
            tuple(map(float, times_s)),
            tuple(tuple(map(float, q)) for q in qs),
            tuple(tuple(map(float, v)) for v in dq),
            (),
            start_s,
            path_tolerance_rad=(PATH_TOLERANCE_RAD,),
        )
        self.sent.add(goal.goal_id)
        self.queued.append(goal)

    def gripper(self, opening: float, start_s: float) -> None:
        """The claw to `opening` (clipped to 0..1) from `start_s`."""
        self.queued.append(GripperGoal(self.next_id(), float(min(max(opening, 0.0), 1.0)), 0.0, start_s))

    def take(self, time_s: float, watched: bool) -> list[ArmGoal]:
        """The goals queued, handed out now; with `watched` (the tracker reports what it drives), a batch with a
        trajectory goal is watched until the tracker shows it."""
        out, self.queued = self.queued, []
        if watched and any(isinstance(g, TrajectoryGoal) for g in out):
            self.unconfirmed.append((time_s, 1, out))
        return out

    def resend(self, goals: list[ArmGoal], shift_s: float) -> list[ArmGoal]:
        """`goals` again with new ids, each `shift_s` later; queued to go out with the next decision."""
        again = [
            dataclasses.replace(
                g,
                goal_id=self.next_id(),
                start_time_s=None if g.start_time_s is None else g.start_time_s + shift_s,
            )
            for g in goals
        ]
        self.sent.update(g.goal_id for g in again if isinstance(g, TrajectoryGoal))
        self.resent += len(again)
        self.queued.extend(again)
        return again
