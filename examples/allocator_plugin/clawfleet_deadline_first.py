"""A clawfleet allocator plug-in: the task due soonest first, each to the free arm that finishes it soonest.

An allocator is made from the scene and answers `allocate(tasks, arms, parts, busy_stations)` with
(task id, arm) pairs (docs/allocators.md). This one uses clawfleet's public helpers for what every allocator
obeys (`Eligibility`: reach and belt stretches) and for time estimates (`TimeCost`: Pinocchio IK and the arm's
speeds), and orders the work its own way.
"""

from __future__ import annotations

import math

from coordinator.allocation import ArmView, Eligibility, PartView, TimeCost, due_s, open_candidates
from coordinator.tasks import Task
from scenes.schema import Scene


class DeadlineFirst:
    """The task due soonest first, each to the free arm that finishes it soonest."""

    name = "deadline_first"

    def __init__(self, scene: Scene) -> None:
        self.scene = scene

    def allocate(
        self, tasks: list[Task], arms: list[ArmView], parts: dict[int, PartView], busy_stations: set[str]
    ) -> list[tuple[int, str]]:
        seconds_for = TimeCost(Eligibility(self.scene, arms))
        free = [a for a in arms if a.free]
        busy, out = set(busy_stations), []
        for task in sorted(open_candidates(tasks, parts, busy_stations), key=lambda t: (due_s(t), t.task_id)):
            if not free:
                break
            if busy.intersection(task.stations):
                continue
            seconds, _, arm = min((seconds_for(a, task, parts[task.part_id]), a.name, a) for a in free)
            if math.isfinite(seconds):
                out.append((task.task_id, arm.name))
                free.remove(arm)
                busy.update(task.stations)
        return out
