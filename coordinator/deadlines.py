"""Deadlines of belt tasks: when a riding part leaves the last stretch any arm reaches, and which assigned
tasks can no longer be met by their arm (so they go back to the pool while another arm still can)."""

from __future__ import annotations

import numpy as np

from coordinator.allocation import ArmView, Eligibility, PartView
from coordinator.tasks import CONVEYOR, Task
from scenes.schema import Conveyor, Scene

SCAN_STEP_M = 0.02


def last_reach_along_belt_m(conveyor: Conveyor, arms: list[ArmView], part_z_m: float) -> float | None:
    """How far along the belt (m from its start) the last point some arm reaches lies, on the centre line at
    a part's height; None if no arm reaches the belt. Scans back from the belt's end, once per cell: each
    miss costs an IK solve, so the per-task deadline below is then a division."""
    for k in range(int(conveyor.length_m / SCAN_STEP_M), -1, -1):
        s = k * SCAN_STEP_M
        x, y, _ = conveyor.point_at(s)
        if any(Eligibility.in_reach(a, (x, y, part_z_m)) for a in arms):
            return s
    return None


_LAST_REACH_M: dict[str, float | None] = {}  # layout -> the belt's last reachable point


def layout_last_reach_m(scene: Scene, arms: list[ArmView]) -> float | None:
    """`last_reach_along_belt_m` of a scene's belt and arms (None without a belt): IK misses cost, so worked out once
    per layout in a process (an env resets often; the dispatcher and a policy allocator ask for the same)."""
    conveyor = scene.conveyor
    if conveyor is None:
        return None
    key = repr((conveyor.model_dump_json(), [(a.model, a.base.xyz, a.base.yaw_rad) for a in scene.arms]))
    if key not in _LAST_REACH_M:
        _LAST_REACH_M[key] = last_reach_along_belt_m(conveyor, arms, conveyor.pose.xyz[2] + 0.015)
    return _LAST_REACH_M[key]


def time_left_s(conveyor: Conveyor, last_reach_m: float | None, part: PartView) -> float | None:
    """Seconds until the riding part passes the last reachable point (None: no arm reaches the belt, or the belt
    stands still)."""
    if last_reach_m is None or conveyor.speed_m_per_s <= 0:
        return None
    along = float(np.dot(part.position[:2] - np.asarray(conveyor.pose.xyz[:2]), np.asarray(conveyor.direction[:2])))
    return max(0.0, last_reach_m - along) / conveyor.speed_m_per_s


def belt_deadline_s(conveyor: Conveyor, last_reach_m: float | None, part: PartView, now_s: float) -> float | None:
    """Sim time at which the riding part passes the last reachable point (None: no arm reaches the belt,
    or the belt stands still)."""
    left = time_left_s(conveyor, last_reach_m, part)
    return None if left is None else now_s + left


def rides_off_within(
    conveyor: Conveyor, last_reach_m: float | None, parts: dict[int, PartView], part_id: int, lead_s: float
) -> bool:
    """Whether a seen belt part passes the last reachable point within `lead_s` (a buffer may still save it)."""
    part = parts.get(part_id)
    left = None if part is None else time_left_s(conveyor, last_reach_m, part)
    return left is not None and left <= lead_s


def cannot_make_it(rules: Eligibility, arm: ArmView, task: Task, part: PartView) -> bool:
    """True for a belt task its arm can no longer meet: the pick point left the arm's reach or its stretch of belt."""
    return task.source == CONVEYOR and not rules.can_serve(arm, task, part)
