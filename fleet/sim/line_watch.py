"""The sim's eyes on the line: turns part poses into line events (arrived, at_station, lost, retired).

The sim reports facts only; what a fact means for the work (a task done, a part
missed) is the coordinator's business. A part `at_station` has rested inside a
station's footprint for `REST_S`; a part resting low outside every station and
off the belt has fallen to the floor and is `lost` (and put back in its pool);
parts resting in a sink station (a route's end that nothing picks from again)
are `retired` after `RETIRE_AFTER_S`, as an operator empties an output tray.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from fleet.sim.world import PartInfo, World
from fleet.sim.world_events import PartSpawned, WorldEvent
from robots.saved_state import SavedState
from scenes.schema import Scene, Station

REST_SPEED_M_PER_S = 0.02
REST_S = 0.2
RETIRE_AFTER_S = 1.0
FLOOR_BAND_M = 0.02
ABOVE_STATION_M = 0.15


@dataclass(frozen=True)
class Event:
    """One line event, as the sim publishes it (`LineEvent` on the bus)."""

    kind: str
    part_id: int
    tick: int
    detail: str
    type_index: int = 0


@dataclass
class _Watch:
    still_since_s: float | None = None
    reported_station: str | None = None
    at_sink_since_s: float | None = None


class WatchState(SavedState, frozen=True):
    still_since_s: float | None
    reported_station: str | None
    at_sink_since_s: float | None


class WatcherState(SavedState, frozen=True):
    """What a `LineWatcher` saves: what it has seen of each part on the line, and how many world events."""

    parts: dict[int, WatchState]
    world_events_seen: int


def sink_stations(scene: Scene) -> set[str]:
    """Stations that end a route and are never picked from again: their parts can be cleared away."""
    finals, passes = set(), set()
    for f in scene.feeders:
        for t in range(len(f.parts)):
            route = scene.route(f.name, t)
            finals.update(route[-1:])
            passes.update(route[:-1])
    fixtures = {s.name for s in scene.stations if s.kind == "fixture"}
    return finals - passes - scene.source_names() - fixtures


def station_containing(stations: list[Station], position: np.ndarray) -> Station | None:
    """The station whose footprint (and the space just above it) holds `position`."""
    for s in stations:
        c, si = math.cos(s.pose.yaw_rad), math.sin(s.pose.yaw_rad)
        dx, dy = position[0] - s.pose.xyz[0], position[1] - s.pose.xyz[1]
        lx, ly = c * dx + si * dy, -si * dx + c * dy
        sx, sy, sz = s.size_m
        if (
            abs(lx) <= sx / 2
            and abs(ly) <= sy / 2
            and s.pose.xyz[2] <= position[2] <= s.pose.xyz[2] + sz + ABOVE_STATION_M
        ):
            return s
    return None


class LineWatcher:
    """Call `update` once per tick with the active parts; it returns the events of that tick."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.sinks = sink_stations(scene)
        self._watch: dict[int, _Watch] = {}
        self._world_events_seen = 0

    def state(self) -> WatcherState:
        return WatcherState(
            parts={
                pid: WatchState(
                    still_since_s=w.still_since_s,
                    reported_station=w.reported_station,
                    at_sink_since_s=w.at_sink_since_s,
                )
                for pid, w in self._watch.items()
            },
            world_events_seen=self._world_events_seen,
        )

    def restore(self, state: WatcherState) -> None:
        self._watch = {
            pid: _Watch(w.still_since_s, w.reported_station, w.at_sink_since_s) for pid, w in state.parts.items()
        }
        self._world_events_seen = state.world_events_seen

    def update(self, world: World, parts: list[PartInfo]) -> list[Event]:
        tick, now = world.tick, world.sim_time_s
        events = [
            Event("arrived", e.part_id, tick, e.feeder, e.type_index)
            for e in self._new_world_events(world)
            if isinstance(e, PartSpawned)
        ]
        retire: list[tuple[int, str]] = []
        active = {p.part_id for p in parts}
        for pid in [pid for pid in self._watch if pid not in active]:
            del self._watch[pid]
        for p in parts:
            w = self._watch.setdefault(p.part_id, _Watch())
            still = float(np.linalg.norm(p.velocity)) < REST_SPEED_M_PER_S
            w.still_since_s = (w.still_since_s if w.still_since_s is not None else now) if still else None
            resting = w.still_since_s is not None and now - w.still_since_s >= REST_S - 1e-9
            station = station_containing(self.scene.stations, p.position)
            if resting and station is not None and station.name != w.reported_station:
                w.reported_station = station.name
                events.append(Event("at_station", p.part_id, tick, station.name))
            if station is None and p.position[2] - p.height_m / 2 < FLOOR_BAND_M:
                retire.append((p.part_id, "fell to the floor"))
                continue
            in_sink = resting and station is not None and station.name in self.sinks
            w.at_sink_since_s = (w.at_sink_since_s if w.at_sink_since_s is not None else now) if in_sink else None
            if in_sink and now - w.at_sink_since_s >= RETIRE_AFTER_S - 1e-9:
                retire.append((p.part_id, ""))
        for pid, why in retire:
            kind, detail = ("lost", why) if why else ("retired", self._watch[pid].reported_station or "")
            events.append(Event(kind, pid, tick, detail))
            world.retire_part(pid)
            del self._watch[pid]
        self._world_events_seen = len(world.events)
        return events

    def _new_world_events(self, world: World) -> list[WorldEvent]:
        return world.events[self._world_events_seen :]
