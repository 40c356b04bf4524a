"""What the physics world records as it steps: typed records in `World.events`, read by the line watcher and the
env (and kept in a world's saved state)."""

from __future__ import annotations

import msgspec


class PartSpawned(msgspec.Struct, frozen=True, tag=True):
    """A feeder released part `part_id` (of its `type_index`-th part type) at `tick`."""

    part_id: int
    feeder: str
    type_index: int
    tick: int


class PartRetired(msgspec.Struct, frozen=True, tag=True):
    """Part `part_id` left the world at `tick` (done with, or lost)."""

    part_id: int
    tick: int


class FeederFull(msgspec.Struct, frozen=True, tag=True):
    """A feeder's release at `tick` was skipped: its drop spot was taken."""

    feeder: str
    tick: int


WorldEvent = PartSpawned | PartRetired | FeederFull
