"""Deadlines of belt tasks: when a riding part leaves the last stretch of belt an arm able to take it reaches, and
which assigned tasks can no longer be met by their arm (so they go back to the pool while another arm still can)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from coordinator.allocation import ArmView, Eligibility, PartView
from coordinator.tasks import CONVEYOR, PartRecord, Task
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


@dataclass(frozen=True)
class BeltReach:
    """How far along the belt (m from its start) a riding part can still be taken: the last point an arm reaches
    that also reaches the part's next station, for a station on a route, a buffer or a bin that takes a belt part's
    colour (in a row of bays, only the bay's own arms); where no arm reaches the station, the last point any arm
    reaches. None: no arm reaches the belt."""

    any_m: float | None
    by_station_m: dict[str, float] = field(default_factory=dict)
    # the buffers an arm reaches that also reaches the station and the belt (where a part for it may be set down)
    buffers_by_station: dict[str, tuple[str, ...]] = field(default_factory=dict)

    def for_station(self, station: str | None) -> float | None:
        return self.by_station_m.get(station, self.any_m)

    def buffers_near(self, station: str) -> tuple[str, ...]:
        return self.buffers_by_station.get(station, ())

    def riding_off(
        self, conveyor: Conveyor, parts: dict[int, PartView], lead_s: float
    ) -> Callable[[PartRecord, str], bool]:
        """Whether a seen belt part passes, within `lead_s`, the last point an arm able to take it to `buffer`
        reaches, and has not passed it yet: the last chance to set it down there. Each buffer by its own arms: a
        buffer upstream (arm_0's on the main job) is asked for while arm_0 can still take the part, not once the
        part nears the belt's end, where only another arm reaches it (measured: three bases in a row rode off on
        assembly_line seed 3 while arm_0 stood idle by a free buffer)."""

        def last_chance(part: PartRecord, buffer: str) -> bool:
            seen = parts.get(part.part_id)
            left = None if seen is None else time_left_s(conveyor, self.for_station(buffer), seen)
            return left is not None and 0.0 < left <= lead_s

        return last_chance


_BELT_REACH: dict[str, BeltReach] = {}  # layout -> its belt reach


def layout_belt_reach(scene: Scene, arms: list[ArmView]) -> BeltReach:
    """The `BeltReach` of a scene's belt, arms and stations (`any_m` None without a belt): IK misses cost, so worked
    out once per layout in a process (an env resets often; the dispatcher and a policy allocator ask for the same)."""
    conveyor = scene.conveyor
    if conveyor is None:
        return BeltReach(None)
    key = repr(
        (
            scene.model_dump_json(include={"conveyor", "stations", "feeders"}),
            [(a.model, a.base.xyz, a.base.yaw_rad) for a in scene.arms],
        )
    )
    if key not in _BELT_REACH:
        z = conveyor.pose.xyz[2] + 0.015
        by_station, buffers = {}, {}
        for station in _routed_stations(scene):
            able = [a for a in arms if Eligibility.reaches_station(a, scene.station(station))]
            last = last_reach_along_belt_m(conveyor, able, z) if able else None
            if last is not None:
                by_station[station] = last
                on_belt = [a for a in able if last_reach_along_belt_m(conveyor, [a], z) is not None]
                buffers[station] = tuple(
                    b for b in scene.buffers() if any(Eligibility.reaches_station(a, scene.station(b)) for a in on_belt)
                )
        _BELT_REACH[key] = BeltReach(last_reach_along_belt_m(conveyor, arms, z), by_station, buffers)
    return _BELT_REACH[key]


def _routed_stations(scene: Scene) -> list[str]:
    """The stations a belt part may be bound for: its feeder's route's first, a buffer, or a bin of its colour (a
    sorted part's, which its colour picks at allocation)."""
    belt = [f for f in scene.feeders if f.into == "conveyor"]
    sorted_into = [s for f in belt for t in range(len(f.parts)) for s in scene.stations_for_colour(f.name, t)]
    named = [f.route[0] for f in belt if f.route] + scene.buffers() + sorted_into
    return list(dict.fromkeys(named))


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


def task_deadline_s(conveyor: Conveyor, reach: BeltReach, task: Task, part: PartView, now_s: float) -> float | None:
    """When a belt task's part rides out of the reach of every arm that could take it to one of its stations (a
    sorted part: any bin of its colour), so that an arm upstream need not hurry for a part one downstream takes."""
    dues = [belt_deadline_s(conveyor, reach.for_station(s), part, now_s) for s in task.all_targets]
    return max((d for d in dues if d is not None), default=None)


def cannot_make_it(rules: Eligibility, arm: ArmView, task: Task, part: PartView) -> bool:
    """True for a belt task its arm can no longer meet: the pick point left the arm's reach or its stretch of belt."""
    return task.source == CONVEYOR and not rules.can_serve(arm, task, part)
