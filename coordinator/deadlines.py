"""Deadlines of belt tasks: when a riding part leaves the last stretch any arm reaches, and which assigned
tasks can no longer be met by their arm (so they go back to the pool while another arm still can)."""

from __future__ import annotations

import numpy as np

from coordinator.allocation import ArmView, Eligibility, PartView
from coordinator.tasks import CONVEYOR, Task

SCAN_STEP_S = 0.5


def belt_deadline_s(part: PartView, arms: list[ArmView], now_s: float, horizon_s: float) -> float | None:
    """Sim time after which no arm can reach the part riding on (None if no arm reaches its path within
    `horizon_s`, e.g. before it rides off the belt's end; a part at rest has no deadline).

    Walks the part's path backwards from the horizon in `SCAN_STEP_S` steps and stops at the first point
    some arm reaches: only the few points past the last arm's reach cost an IK check.
    """
    if not np.any(part.velocity):
        return None
    for k in range(int(max(horizon_s, 0.0) / SCAN_STEP_S), -1, -1):
        t = k * SCAN_STEP_S
        if any(Eligibility.in_reach(a, part.position + part.velocity * t) for a in arms):
            return now_s + t
    return None


def cannot_make_it(rules: Eligibility, arm: ArmView, task: Task, part: PartView) -> bool:
    """True for a belt task its arm can no longer meet: the pick point left the arm's reach or its stretch of belt."""
    return task.source == CONVEYOR and not rules.can_serve(arm, task, part)
