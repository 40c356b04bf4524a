"""The line's parts as perception sees them, for one running line: the line's events say which parts exist and where
the line put them (`perception.line_parts` binds each to a camera's track), the tracks say where they are; one
`PartsState` a frame, on `seen/parts`, for the coordinator and the controllers (`docs/perception.md`)."""

from __future__ import annotations

import math
from collections.abc import Iterable

import msgspec
import numpy as np

from coordinator.ledger import EVENT_KINDS
from fleet.bus.codec import DropCounter
from fleet.bus.message_checks import parts_problem
from fleet.bus.messages import LineEvent, PartsState
from perception.line_parts import LineParts
from perception.looks import PartLook
from perception.seen_ticks import SeenTicks
from perception.tracks import Track
from scenes.schema import Scene


def station_spread_m(scene: Scene, name: str) -> float:
    """How far from a station's centre a part set down in it may lie: half its diagonal."""
    sx, sy, _ = scene.station(name).size_m
    return 0.5 * math.hypot(sx, sy)


class LineSight:
    """Events (`event`, held until the frame whose tick reaches them) and frames' tracks (`update`) in, the line's
    seen parts out (`message`). `kinds`: each (feeder, type index)'s kind, `looks` by kind (their sizes)."""

    def __init__(self, scene: Scene, looks: list[PartLook], kinds: dict[tuple[str, int], int], velocity_at) -> None:
        self.scene, self.looks, self.kinds = scene, looks, kinds
        self.line_parts = LineParts(velocity_at)
        self.types: dict[int, tuple[str, int]] = {}  # by part: (feeder, type index), as the events name it
        self.held: list[tuple[int, str, LineEvent]] = []  # (its number in the line's order, key, event)
        self.events_seen = 0
        self.events_applied = 0  # the line's events applied so far (in its order): what a frame's parts reflect
        self.released = 0

    def event(self, key: str, e: LineEvent, drops: DropCounter) -> None:
        """An event of the line: counted now, applied at the first frame taken after the sim published it."""
        number = self.events_seen
        self.events_seen += 1
        problem = self._problem(e)
        if problem:
            drops.drop(key, problem)
        else:
            self.held.append((number, key, e))

    def _problem(self, e: LineEvent) -> str:
        if e.kind not in EVENT_KINDS:
            return f"unknown event kind {e.kind!r}"
        if e.tick < 0 or e.part_id < 0:
            return "an event with a negative tick or part id"
        if e.kind == "arrived" and (e.detail, e.type_index) not in self.kinds:
            return f"part {e.part_id} arrived from no feeder and type of this line ({e.detail!r}, {e.type_index})"
        if e.kind in ("at_station", "retired") and e.detail not in {s.name for s in self.scene.stations}:
            return f"{e.kind} at no station of this line ({e.detail!r})"
        return ""

    def apply_events(self, up_to_tick: int, published: int | None = None) -> None:
        """The held events of ticks up to `up_to_tick`, in the order they came; with `published` (the events the
        sim had published when the frame was taken), only those: an event of the frame's own tick published after
        it waits for the next frame, however soon it arrives, so every run binds the same."""
        later = []
        for number, key, e in self.held:
            if e.tick > up_to_tick or (published is not None and number >= published):
                later.append((number, key, e))
                continue
            self.events_applied = max(self.events_applied, number + 1)
            time_s = e.tick / self.scene.control_hz
            if e.kind == "arrived":
                self._arrived(e, time_s)
            elif e.kind == "at_station" and e.part_id in self.types:
                spot = self._station_spot(e.detail, self.types[e.part_id])
                self.line_parts.moved(e.part_id, spot, time_s, station_spread_m(self.scene, e.detail))
            elif e.kind in ("lost", "retired"):
                self.line_parts.gone(e.part_id)
        self.held = later

    def _arrived(self, e: LineEvent, time_s: float) -> None:
        feeder = self.scene.feeder(e.detail)
        kind = self.kinds[e.detail, e.type_index]
        height_m = feeder.parts[e.type_index].size_m[2]
        if feeder.into == "conveyor":
            x, y, z = self.scene.conveyor.point_at(self.scene.drop_along_m(feeder))
            spot, spread = np.array([x, y, z + height_m]), feeder.lateral_jitter_m
        else:
            spot, spread = (
                self._station_spot(feeder.into, (e.detail, e.type_index)),
                station_spread_m(self.scene, feeder.into),
            )
        self.types[e.part_id] = (e.detail, e.type_index)
        self.released += 1
        self.line_parts.arrived(e.part_id, kind, spot, time_s, spread)

    def _station_spot(self, station: str, part_type: tuple[str, int]) -> np.ndarray:
        x, y, z = self.scene.station(station).pose.xyz
        height_m = self.scene.feeder(part_type[0]).parts[part_type[1]].size_m[2]
        return np.array([x, y, z + height_m])

    def update(self, camera: str, tracks: list[Track], time_s: float) -> None:
        self.line_parts.update(camera, tracks, time_s)

    def message(self, tick: int, time_s: float) -> PartsState:
        """The parts seen as of frame `tick`: each at its centre (its top face's, half its height down), turned as
        its track says (about the vertical), riding the surface under it, sized as its type is."""
        ids, feeders, types, positions, quaternions, velocities, sizes = [], [], [], [], [], [], []
        for part, top_m in self.line_parts.seen(time_s):
            feeder, type_index = self.types[part.part_id]
            size = tuple(self.scene.feeder(feeder).parts[type_index].size_m)
            yaw = part.yaw_rad if size[0] >= size[1] else part.yaw_rad - math.pi / 2  # the body's x is its longer side
            ids.append(part.part_id)
            feeders.append(feeder)
            types.append(type_index)
            positions += [float(top_m[0]), float(top_m[1]), float(top_m[2] - size[2] / 2)]
            quaternions += [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]
            velocities += [float(v) for v in self.line_parts.velocity_at(top_m)]
            sizes += [float(v) for v in size]
        return PartsState(
            tick,
            time_s,
            tuple(ids),
            tuple(feeders),
            tuple(types),
            tuple(positions),
            tuple(quaternions),
            tuple(velocities),
            tuple(sizes),
            self.events_applied,  # not those heard: an event that came early must not change the frame's bits
        )

    def report(self) -> dict:
        """Parts released and parts ever seen (bound to a track)."""
        return {"parts_released": self.released, "parts_seen": len(self.line_parts.first_seen_s)}


def seen_ticks_of(scene: Scene) -> SeenTicks:
    """The frame ticks of the line's sight: every fixed camera of `scene` (`--perception cameras` renders them all)."""
    rates = [c.rate_hz for c in scene.cameras if c.arm is None]
    if not rates:
        raise ValueError(f"the scene {scene.name} has no fixed camera to see the line with")
    return SeenTicks(rates, scene.control_hz)


def newest_up_to(frames: Iterable[PartsState], tick: int) -> PartsState | None:
    """The newest of perception's parts messages (oldest first) taken no later than `tick` (None: none was)."""
    usable = [m for m in frames if m.tick <= tick]
    return usable[-1] if usable else None


def carried_to(msg: PartsState, tick: int, control_hz: float) -> PartsState:
    """Perception's parts of a frame, carried to control tick `tick` by the motion it gives each (a belt part rides
    on): what a node acting at `tick` takes them to be, not where they were when the frame was taken."""
    ahead_s = (tick - msg.tick) / control_hz
    positions = tuple(p + v * ahead_s for p, v in zip(msg.positions, msg.velocities))
    return msgspec.structs.replace(msg, tick=tick, sim_time_s=tick / control_hz, positions=positions)


def seen_parts_problem(msg: PartsState, ticks: SeenTicks) -> str:
    """Why a decoded parts message on `seen/parts` cannot be perception's ("" if it can): of a tick no camera takes
    a frame at, or arrays that do not fit its ids."""
    if not ticks.due(msg.tick):
        return f"seen parts of tick {msg.tick}, when no camera takes a frame"
    return parts_problem(msg)
