"""The world's feeders: parts released when due onto a free spot, placed, spawned on demand and retired."""

from __future__ import annotations

import math

from fleet.sim.arm import yaw_pose
from fleet.sim.parts import FeederClock, SimPart, park
from fleet.sim.world_events import FeederFull, PartRetired, PartSpawned
from scenes.schema import Feeder
from scenes.shapes import WALL_M


class WorldFeeders:
    """Feeding and retiring parts: one concern of `World`, kept apart (it shares the world's scene and parts)."""

    def _release_due_parts(self) -> None:
        t = self.sim_time_s
        for clock in self.feeders:
            while clock.next_time_s <= t:
                if self._drop_spot(clock) is None:
                    clock.held_s += self.control_dt_s  # a part due waits upstream for a free spot
                    break
                self._spawn(clock)
                clock.advance()

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
        scene = self.scene_model
        if feeder.into == "conveyor":
            return scene.conveyor.point_at(scene.drop_along_m(feeder), lateral_m)
        x, y, z = scene.station(feeder.into).pose.xyz
        return x, y, z + WALL_M + 0.01

    def _nobody_within(self, xy: tuple[float, ...], radius_m: float) -> bool:
        """No part in play has its centre within `radius_m` of this spot, horizontally."""
        x, y = xy[0], xy[1]
        return all(
            math.hypot(p.entity.pose.p[0] - x, p.entity.pose.p[1] - y) >= radius_m for p in self.parts if p.active
        )

    def _spawn(self, clock: FeederClock) -> None:
        feeder = clock.feeder
        type_index = int(clock.rng.integers(len(feeder.parts)))
        lateral = float(clock.rng.uniform(-1, 1)) * feeder.lateral_jitter_m
        yaw = float(clock.rng.uniform(-math.pi, math.pi))
        free = self._free_slots(clock, type_index)
        if not free:
            clock.skipped_full += 1
            self.events.append(FeederFull(feeder.name, self.tick))
            return
        # `spawn_now` asks for a part now
        spot = self._drop_spot(clock, lateral) or self._drop_point(feeder, lateral)
        self._put(self.parts[free[0]], spot, yaw)
        clock.spawned += 1

    def _free_slots(self, clock: FeederClock, type_index: int) -> list[int]:
        """The feeder's pooled parts of this type not in play now (indices into `self.parts`)."""
        return [s for s in clock.slots if self.parts[s].part_id is None and self.parts[s].type_index == type_index]

    def _put(self, part: SimPart, surface_xyz: tuple[float, float, float], yaw_rad: float) -> int:
        """Set a pooled part down, bottom on `surface_xyz`, give it the next id and log its spawn."""
        x, y, z = surface_xyz
        part.entity.set_pose(yaw_pose((x, y, z + part.height_m / 2 + 0.001), yaw_rad))
        part.body.set_kinematic(False)
        part.body.set_linear_velocity([0.0, 0.0, 0.0])
        part.body.set_angular_velocity([0.0, 0.0, 0.0])
        part.part_id = self.next_part_id
        self.next_part_id += 1
        self.events.append(PartSpawned(part.part_id, part.feeder, part.type_index, self.tick))
        return part.part_id

    def place_part(
        self, feeder_name: str, type_index: int, surface_xyz: tuple[float, float, float], yaw_rad: float = 0.0
    ) -> int:
        """Set a free part of a feeder's pool down at a chosen spot (the env's tasks); returns its id."""
        clock = self._clock(feeder_name)
        free = self._free_slots(clock, type_index)
        if not free:
            raise RuntimeError(f"feeder {feeder_name!r} has no free part of type {type_index} left in its pool")
        return self._put(self.parts[free[0]], surface_xyz, yaw_rad)

    def _clock(self, feeder_name: str) -> FeederClock:
        clock = next((c for c in self.feeders if c.feeder.name == feeder_name), None)
        if clock is None:
            raise KeyError(f"no feeder {feeder_name!r}; feeders: {', '.join(c.feeder.name for c in self.feeders)}")
        return clock

    def spawn_now(self, feeder_name: str) -> int:
        """Release one part from a feeder at once (trials and tests); returns its id."""
        clock = self._clock(feeder_name)
        before = self.next_part_id
        self._spawn(clock)
        if self.next_part_id == before:
            raise RuntimeError(f"feeder {feeder_name!r} has no free part left in its pool")
        return before

    def retire_part(self, part_id: int) -> None:
        """Take a finished or lost part off the stage, back into its pool."""
        part = self._part(part_id)
        park(part.entity, part.body, part.slot)
        part.part_id = None
        self.events.append(PartRetired(part_id, self.tick))
