"""What the physics world records as it steps: typed records in `World.events`, read by the line watcher and the
env (and kept in a world's saved state)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PartSpawned:
    """A feeder released part `part_id` (of its `type_index`-th part type) at `tick`."""

    part_id: int
    feeder: str
    type_index: int
    tick: int


@dataclass(frozen=True)
class PartRetired:
    """Part `part_id` left the world at `tick` (done with, or lost)."""

    part_id: int
    tick: int


@dataclass(frozen=True)
class FeederFull:
    """A feeder's release at `tick` was skipped: its drop spot was taken."""

    feeder: str
    tick: int


WorldEvent = PartSpawned | PartRetired | FeederFull
