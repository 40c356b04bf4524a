"""Who does which task: the allocator interface, reach and zone rules, and the nearest-free-arm allocator.

An allocator sees the pending tasks, the arms (free or not) and where the parts
are, and returns (task id, arm) pairs. Every allocator obeys the same rules:
an arm takes a task only if it reaches both the pick point and the target;
a station serves one task at a time; and a conveyor stretch belongs to the arm
whose base is nearest (with a margin), so neighbours never reach for the same
spot of belt.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from coordinator.tasks import CONVEYOR, Task
from robots.top_down import TopDownIK
from scenes.schema import Scene

EARLIEST_ARRIVAL_S = 0.6  # the soonest an arm can be above a part
PICK_LEAD_S = 1.5  # about the time an arm needs to arrive above a part
GRASP_WINDOW_S = 1.5  # descend, close and lift: the part must stay in reach this long after arrival
HOVER_M = 0.1  # reach is checked this far above the part or the station surface
CELL_MARGIN_M = 0.06
GRID_M = 0.01


class CachedReach:
    """Whether an arm can point its claw straight down at a spot, by Pinocchio IK, cached on a 1 cm grid."""

    def __init__(self, top_down: TopDownIK) -> None:
        self.top_down = top_down
        self._cache: dict[tuple[int, int, int], bool] = {}

    def __call__(self, point) -> bool:
        key = tuple(int(round(float(v) / GRID_M)) for v in point[:3])
        if key not in self._cache:
            self._cache[key] = self.top_down.reachable(np.array(key, float) * GRID_M)
        return self._cache[key]


@dataclass(frozen=True)
class ArmView:
    """What an allocator knows of an arm: where it stands, whether it can take work, and what it can reach."""

    name: str
    base_xyz: tuple[float, float, float]
    free: bool
    reach: Callable[[np.ndarray], bool] = field(compare=False, repr=False)


@dataclass(frozen=True)
class PartView:
    """Where a part is now and how it moves (world frame, metres, m/s)."""

    position: np.ndarray
    velocity: np.ndarray


class Allocator(Protocol):
    """Chooses arms for pending tasks; must be deterministic for the same inputs."""

    name: str

    def allocate(self, tasks: list[Task], arms: list[ArmView], parts: dict[int, PartView], busy_stations: set[str]) -> list[tuple[int, str]]:
        ...


def horizontal_distance_m(a, b) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


class Eligibility:
    """The rules every allocator shares: reach, and conveyor stretches owned by the nearest arm."""

    def __init__(self, scene: Scene, arms: list[ArmView]) -> None:
        self.scene = scene
        self.bases = {a.name: a.base_xyz for a in arms}

    @staticmethod
    def in_reach(arm: ArmView, point) -> bool:
        return arm.reach(np.asarray(point, float) + [0.0, 0.0, HOVER_M])

    def owns_belt_point(self, arm: ArmView, point) -> bool:
        mine = horizontal_distance_m(arm.base_xyz, point)
        return all(mine + CELL_MARGIN_M <= horizontal_distance_m(b, point) for n, b in self.bases.items() if n != arm.name)

    def pick_point(self, task: Task, part: PartView) -> np.ndarray:
        """Where the arm will meet the part: ahead along the belt for conveyor parts."""
        if task.source == CONVEYOR:
            return part.position + part.velocity * PICK_LEAD_S
        return part.position

    def can_serve(self, arm: ArmView, task: Task, part: PartView) -> bool:
        station = self.scene.station(task.target)
        if not self.in_reach(arm, (*station.pose.xyz[:2], station.surface_z_m)):
            return False
        pick = self.pick_point(task, part)
        if task.source != CONVEYOR:
            return self.in_reach(arm, pick)
        if not self.owns_belt_point(arm, pick):
            return False
        soonest = part.position + part.velocity * EARLIEST_ARRIVAL_S
        latest = pick + part.velocity * GRASP_WINDOW_S
        return self.in_reach(arm, soonest) and self.in_reach(arm, latest)

    def cost_m(self, arm: ArmView, task: Task, part: PartView) -> float:
        """A distance-only cost: how far the pick point is from the arm's base."""
        return horizontal_distance_m(arm.base_xyz, self.pick_point(task, part))


class NearestFreeArm:
    """Oldest task first, each to the nearest free arm that can serve it: the simple baseline."""

    name = "nearest"

    def __init__(self, scene: Scene) -> None:
        self.scene = scene

    def allocate(self, tasks: list[Task], arms: list[ArmView], parts: dict[int, PartView], busy_stations: set[str]) -> list[tuple[int, str]]:
        rules = Eligibility(self.scene, arms)
        free = [a for a in arms if a.free]
        busy = set(busy_stations)
        out = []
        for task in sorted(tasks, key=lambda t: (t.created_s, t.task_id)):
            part = parts.get(task.part_id)
            if part is None or busy.intersection(task.stations):
                continue
            options = [a for a in free if rules.can_serve(a, task, part)]
            if not options:
                continue
            arm = min(options, key=lambda a: (rules.cost_m(a, task, part), a.name))
            out.append((task.task_id, arm.name))
            free.remove(arm)
            busy.update(task.stations)
        return out
