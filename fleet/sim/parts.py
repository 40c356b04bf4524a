"""Parts and their feeders: a fixed pool of rigid bodies per feeder, parked out of the way until spawned.

A fixed pool keeps the set of bodies in the physics scene constant, so the
whole world state can be packed and restored exactly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import sapien

from scenes.schema import Feeder, PartType

PARK_Z_M = -20.0
CYLINDER_AXIS_TO_Z = [math.cos(-math.pi / 4), 0.0, math.sin(-math.pi / 4), 0.0]  # PhysX cylinders lie along x


@dataclass
class SimPart:
    """One pooled body. `part_id` is None while parked; ids count up over the run, never reused."""

    slot: int
    feeder: str
    type_index: int
    part_type: PartType
    entity: sapien.Entity
    body: sapien.physx.PhysxRigidDynamicComponent
    part_id: int | None = None

    @property
    def active(self) -> bool:
        return self.part_id is not None

    @property
    def width_m(self) -> float:
        """The narrower horizontal size: what a claw closes on."""
        return float(min(self.part_type.size_m[0], self.part_type.size_m[1]))

    @property
    def height_m(self) -> float:
        return float(self.part_type.size_m[2])


def build_part(
    scene: sapien.Scene, part_type: PartType, slot: int, name: str
) -> tuple[sapien.Entity, sapien.physx.PhysxRigidDynamicComponent]:
    """A dynamic body for one part type, mass from the type, friction from the type."""
    sx, sy, sz = part_type.size_m
    material = sapien.physx.PhysxMaterial(part_type.friction, part_type.friction, 0.0)
    builder = scene.create_actor_builder()
    if part_type.kind == "box":
        volume = sx * sy * sz
        builder.add_box_collision(
            half_size=[sx / 2, sy / 2, sz / 2], material=material, density=part_type.mass_kg / volume
        )
    else:
        r = sx / 2
        volume = math.pi * r * r * sz
        builder.add_cylinder_collision(
            pose=sapien.Pose([0, 0, 0], CYLINDER_AXIS_TO_Z),
            radius=r,
            half_length=sz / 2,
            material=material,
            density=part_type.mass_kg / volume,
        )
    builder.set_name(name)
    entity = builder.build()
    body = entity.find_component_by_type(sapien.physx.PhysxRigidDynamicComponent)
    park(entity, body, slot)
    return entity, body


def park(entity: sapien.Entity, body: sapien.physx.PhysxRigidDynamicComponent, slot: int) -> None:
    """Move a pooled body far below the cell, frozen, where nothing touches it."""
    body.set_kinematic(True)
    entity.set_pose(sapien.Pose([3.0 * (slot % 40), 3.0 * (slot // 40), PARK_Z_M]))


@dataclass
class FeederClock:
    """When a feeder releases its next part; its random stream is part of the world state."""

    feeder: Feeder
    rng: np.random.Generator
    next_time_s: float = math.inf
    schedule_index: int = 0
    spawned: int = 0
    skipped_full: int = 0
    held_s: float = 0.0  # sim seconds a due part waited upstream for a free spot to be dropped on
    slots: list[int] = field(default_factory=list)

    def start(self) -> None:
        arrival = self.feeder.arrival
        if arrival.schedule_s is not None:
            self.next_time_s = sorted(arrival.schedule_s)[0] if arrival.schedule_s else math.inf
        else:
            self.next_time_s = arrival.first_at_s

    def advance(self) -> None:
        """Step to the next release time: the next scheduled one, or an exponential gap for a rate."""
        arrival = self.feeder.arrival
        if arrival.schedule_s is not None:
            self.schedule_index += 1
            times = sorted(arrival.schedule_s)
            self.next_time_s = times[self.schedule_index] if self.schedule_index < len(times) else math.inf
        else:
            self.next_time_s += float(self.rng.exponential(60.0 / arrival.rate_per_min))
