"""The world's parts and their feeders: a fixed pool of bodies per feeder, released when due onto a free spot,
placed, spawned on demand and retired. It owns the pool, the feeders' clocks and the part ids; the world hands it
the physics scene to build in and the tick, and takes the events it returns."""

from __future__ import annotations

import math

import numpy as np
import sapien

from fleet.sim.arm import yaw_pose
from fleet.sim.parts import FeederClock, SimPart, build_part, park
from fleet.sim.world_events import FeederFull, PartRetired, PartSpawned, WorldEvent
from robots.saved_state import SavedState, generator_of, generator_state
from scenes.schema import Feeder, Scene
from scenes.shapes import WALL_M, station_spots

DROP_GAP_M = 0.01  # a feeder drops a part only this far clear of the parts already there (beyond their sizes)


def feeder_streams(seed: int, n_feeders: int) -> list[np.random.Generator]:
    """One independent random stream per feeder, all from one seed (the scene's)."""
    return [np.random.default_rng(s) for s in np.random.SeedSequence(seed).spawn(max(1, n_feeders))][:n_feeders]


class FeederClockState(SavedState, frozen=True):
    """What a feeder's clock saves: where its random stream stands, its next release, what it released."""

    rng: str  # `generator_state`
    next_time_s: float
    schedule_index: int
    spawned: int
    skipped_full: int
    held_s: float


class PartFeeders:
    """Every feeder's pool of parts (parked until released) and its clock; the ids given out, never reused."""

    def __init__(self, physics: sapien.Scene, scene: Scene) -> None:
        self.scene = scene
        self.parts: list[SimPart] = []
        self.clocks: list[FeederClock] = []
        self.next_part_id = 0
        for feeder, stream in zip(scene.feeders, feeder_streams(scene.seed, len(scene.feeders))):
            clock = FeederClock(feeder, stream)
            for _ in range(feeder.capacity):
                for t_index, part_type in enumerate(feeder.parts):
                    slot = len(self.parts)
                    entity, body = build_part(physics, part_type, slot, f"{feeder.name}_{slot}")
                    self.parts.append(SimPart(slot, feeder.name, t_index, part_type, entity, body))
                    clock.slots.append(slot)
            clock.start()
            self.clocks.append(clock)
        # where each feeder sets parts down, worked out once: how far apart, and a station feeder's spots
        self._drop_spacing_m = {
            f.name: max(math.hypot(p.size_m[0], p.size_m[1]) for p in f.parts) + DROP_GAP_M for f in scene.feeders
        }
        self._station_spots = {
            f.name: station_spots(
                scene.station(f.into), self._drop_spacing_m[f.name], max(max(p.size_m[0], p.size_m[1]) for p in f.parts)
            )
            for f in scene.feeders
            if f.into != "conveyor"
        }

    # --- releasing ------------------------------------------------------------------
    def release_due(self, tick: int, sim_time_s: float, tick_s: float) -> list[WorldEvent]:
        """Every part due by `sim_time_s` set down where a spot is free; a due part with none waits upstream."""
        events: list[WorldEvent] = []
        for clock in self.clocks:
            while clock.next_time_s <= sim_time_s:
                if self._drop_spot(clock) is None:
                    clock.held_s += tick_s  # a part due waits upstream for a free spot
                    break
                events += self._spawn(clock, tick)
                clock.advance()
        return events

    def _drop_spot(self, clock: FeederClock, lateral_m: float = 0.0) -> tuple[float, float, float] | None:
        """Where a feeder's next part goes down, or None while there is no free spot (the part waits upstream: it is
        released at the first tick one frees up, never dropped onto another; the feeder's later draws keep their
        times, so its rate stays). On the conveyor: its drop point, free once the belt has carried the last part
        clear of it. Into a station: the free spot nearest its centre on a grid a part's footprint apart (parts lie
        side by side in one layer, as a person or a feeder would set them down)."""
        feeder = clock.feeder
        spacing_m = self._drop_spacing_m[feeder.name]
        if feeder.into == "conveyor":
            clear = self._nobody_within(self._drop_point(feeder), spacing_m + feeder.lateral_jitter_m)
            return self._drop_point(feeder, lateral_m) if clear else None
        for x, y in self._station_spots[feeder.name]:
            if self._nobody_within((x, y), 0.75 * spacing_m):
                return x, y, self._drop_point(feeder)[2]
        return None

    def _drop_point(self, feeder: Feeder, lateral_m: float = 0.0) -> tuple[float, float, float]:
        """The feeder's drop point on the conveyor (`lateral_m` off its centre line), or just above its station's
        floor at its centre."""
        if feeder.into == "conveyor":
            return self.scene.conveyor.point_at(self.scene.drop_along_m(feeder), lateral_m)
        x, y, z = self.scene.station(feeder.into).pose.xyz
        return x, y, z + WALL_M + 0.01

    def _nobody_within(self, xy: tuple[float, ...], radius_m: float) -> bool:
        """No part in play has its centre within `radius_m` of this spot, horizontally."""
        x, y = xy[0], xy[1]
        return all(
            math.hypot(p.entity.pose.p[0] - x, p.entity.pose.p[1] - y) >= radius_m for p in self.parts if p.active
        )

    def _spawn(self, clock: FeederClock, tick: int) -> list[WorldEvent]:
        feeder = clock.feeder
        type_index = int(clock.rng.integers(len(feeder.parts)))
        lateral = float(clock.rng.uniform(-1, 1)) * feeder.lateral_jitter_m
        yaw = float(clock.rng.uniform(-math.pi, math.pi))
        free = self._free_slots(clock, type_index)
        if not free:
            clock.skipped_full += 1
            return [FeederFull(feeder.name, tick)]
        # `spawn_now` asks for a part now
        spot = self._drop_spot(clock, lateral) or self._drop_point(feeder, lateral)
        _, spawned = self._put(self.parts[free[0]], spot, yaw, tick)
        clock.spawned += 1
        return [spawned]

    def _free_slots(self, clock: FeederClock, type_index: int) -> list[int]:
        """The feeder's pooled parts of this type not in play now (indices into `parts`)."""
        return [s for s in clock.slots if self.parts[s].part_id is None and self.parts[s].type_index == type_index]

    def _put(
        self, part: SimPart, surface_xyz: tuple[float, float, float], yaw_rad: float, tick: int
    ) -> tuple[int, PartSpawned]:
        """Set a pooled part down, bottom on `surface_xyz`, and give it the next id; its spawn event."""
        x, y, z = surface_xyz
        part.entity.set_pose(yaw_pose((x, y, z + part.height_m / 2 + 0.001), yaw_rad))
        part.body.set_kinematic(False)
        part.body.set_linear_velocity([0.0, 0.0, 0.0])
        part.body.set_angular_velocity([0.0, 0.0, 0.0])
        part.part_id = self.next_part_id
        self.next_part_id += 1
        return part.part_id, PartSpawned(part.part_id, part.feeder, part.type_index, tick)

    # --- asked for --------------------------------------------------------------------
    def place(
        self, feeder_name: str, type_index: int, surface_xyz: tuple[float, float, float], yaw_rad: float, tick: int
    ) -> tuple[int, PartSpawned]:
        """Set a free part of a feeder's pool down at a chosen spot (the env's scenarios): its id and event."""
        free = self._free_slots(self.clock(feeder_name), type_index)
        if not free:
            raise RuntimeError(f"feeder {feeder_name!r} has no free part of type {type_index} left in its pool")
        return self._put(self.parts[free[0]], surface_xyz, yaw_rad, tick)

    def spawn_now(self, feeder_name: str, tick: int) -> tuple[int, list[WorldEvent]]:
        """Release one part from a feeder at once (trials and tests): its id and the events."""
        before = self.next_part_id
        events = self._spawn(self.clock(feeder_name), tick)
        if self.next_part_id == before:
            raise RuntimeError(f"feeder {feeder_name!r} has no free part left in its pool")
        return before, events

    def retire(self, part_id: int, tick: int) -> PartRetired:
        """Take a finished or lost part off the stage, back into its pool."""
        part = self.part(part_id)
        park(part.entity, part.body, part.slot)
        part.part_id = None
        return PartRetired(part_id, tick)

    def clock(self, feeder_name: str) -> FeederClock:
        clock = next((c for c in self.clocks if c.feeder.name == feeder_name), None)
        if clock is None:
            raise KeyError(f"no feeder {feeder_name!r}; feeders: {', '.join(c.feeder.name for c in self.clocks)}")
        return clock

    def part(self, part_id: int) -> SimPart:
        for p in self.parts:
            if p.part_id == part_id:
                return p
        raise KeyError(f"no active part {part_id}")

    # --- state ------------------------------------------------------------------------
    def clock_states(self) -> list[FeederClockState]:
        """Each feeder clock as a snapshot keeps it."""
        return [
            FeederClockState(
                rng=generator_state(c.rng),
                next_time_s=c.next_time_s,
                schedule_index=c.schedule_index,
                spawned=c.spawned,
                skipped_full=c.skipped_full,
                held_s=c.held_s,
            )
            for c in self.clocks
        ]

    def restore(self, part_ids: list[int | None], clock_states: list[FeederClockState], next_part_id: int) -> None:
        """The pool's ids and the clocks as `clock_states` has them (the bodies' poses are the physics')."""
        for part, part_id in zip(self.parts, part_ids):
            part.part_id = part_id
            part.body.set_kinematic(part_id is None)
        for clock, saved in zip(self.clocks, clock_states):
            clock.rng.bit_generator.state = generator_of(saved.rng).bit_generator.state  # in place
            clock.next_time_s = saved.next_time_s
            clock.schedule_index = saved.schedule_index
            clock.spawned = saved.spawned
            clock.skipped_full = saved.skipped_full
            clock.held_s = saved.held_s
        self.next_part_id = next_part_id

    def reseed(self, seed: int) -> None:
        """The feeders' random streams (arrival gaps, part types, drop offsets) from `seed`, as a world built with
        that scene seed has them."""
        for clock, stream in zip(self.clocks, feeder_streams(seed, len(self.clocks))):
            clock.rng = stream
