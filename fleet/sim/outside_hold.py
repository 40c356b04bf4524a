"""Arms an outside client (ROS) drives: one small state machine per arm, the one place that says whether an arm is
taken.

    free --an outside goal accepted--> taken --no outside goal drives it--> letting go --RELEASE_S--> free
                                         ^-------- an outside goal accepted ---------'

An arm is taken while any goal an outside client sent drives it (trajectory or claw, running or waiting to
start), and for `OUTSIDE_RELEASE_S` after the last one stops driving it, however it stopped: it reached its end,
it was preempted by a shorter one, cancelled (a hold of the client's), refused, or aborted (an e-stop, a
tolerance). So a 30 s goal replaced by a 1 s goal lets go 2 s after the 1 s goal, not the 30 s one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from robots.saved_state import SavedState
from robots.tracker import ArmTracker

OUTSIDE_RELEASE_S = 2.0  # an outside driver lets go of an arm this long (sim s) after its last goal stops driving it


class OutsideHoldState(SavedState, frozen=True):
    """What `OutsideHold` saves: the outside goals of each arm taken, and when each is let go."""

    goal_ids: dict[str, set[int]]
    until_s: dict[str, float]


@dataclass
class OutsideHold:
    """Which arms outside clients drive, from the goals they sent and what each arm's tracker drives now."""

    release_s: float = OUTSIDE_RELEASE_S
    goal_ids: dict[str, set[int]] = field(default_factory=dict)  # arm -> outside goals accepted while it is taken
    until_s: dict[str, float] = field(default_factory=dict)  # arm -> when it is let go (inf: a goal drives it)

    def state(self) -> OutsideHoldState:
        return OutsideHoldState(goal_ids={a: set(g) for a, g in self.goal_ids.items()}, until_s=dict(self.until_s))

    def restore(self, state: OutsideHoldState) -> None:
        self.goal_ids = {a: set(g) for a, g in state.goal_ids.items()}
        self.until_s = dict(state.until_s)

    def take(self, arm: str, goal_id: int) -> bool:
        """An outside goal for `arm` was accepted; whether that takes it (it was free: its own controller's goals
        still waiting must be cancelled)."""
        first = arm not in self.until_s
        self.goal_ids.setdefault(arm, set()).add(goal_id)
        self.until_s[arm] = math.inf
        return first

    def taken(self, arm: str, tracker: ArmTracker, now_s: float) -> bool:
        """Whether `arm` is taken at `now_s` (its state moved on first: letting go once no outside goal drives it,
        free once `release_s` passed)."""
        until = self.until_s.get(arm)
        if until is None:
            return False
        if self._driving(arm, tracker):
            self.until_s[arm] = math.inf
            return True
        if until == math.inf:
            self.until_s[arm] = until = now_s + self.release_s
        if now_s < until:
            return True
        del self.until_s[arm]
        self.goal_ids.pop(arm, None)
        return False

    def let_go_at(self, arm: str) -> float:
        """When `arm` is let go (inf while an outside goal drives it; -inf when it is free)."""
        return self.until_s.get(arm, -math.inf)

    def _driving(self, arm: str, tracker: ArmTracker) -> bool:
        ids = self.goal_ids.get(arm, set())
        return tracker.goal_id in ids or any(g in ids for g in tracker.claw.goal_ids())
