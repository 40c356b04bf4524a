"""What the dispatcher decides, as orders to arms: an assignment, a cancel, a motion grant; and one decision's orders
with the arms' nearest neighbours then. The coordinator node turns each into a bus message."""

from __future__ import annotations

from dataclasses import dataclass

from coordinator.guard import NearestPair


@dataclass(frozen=True)
class AssignOrder:
    """Take `task_id`: pick part `part_id` from a surface at `surface_z_m` moving at `surface_velocity`,
    place it at `place_xyz` (the part's bottom, world frame, metres)."""

    arm: str
    task_id: int
    part_id: int
    surface_z_m: float
    place_xyz: tuple[float, float, float]
    surface_velocity: tuple[float, float, float]


@dataclass(frozen=True)
class CancelOrder:
    """Drop the task on part `part_id`: the arm can no longer meet it (another arm may)."""

    arm: str
    part_id: int


@dataclass(frozen=True)
class GrantOrder:
    """The answer to motion request `request_seq`: `grant` (the move starts at `start_s`) or `deny` (`conflict_arm`
    stands in the way); `min_separation_m` is the closest approach checked (inf: no neighbour)."""

    arm: str
    request_seq: int
    decision: str
    conflict_arm: str
    min_separation_m: float
    start_s: float | None


Order = AssignOrder | CancelOrder | GrantOrder


@dataclass(frozen=True)
class Decision:
    """What one decision produced: the orders in publishing order, and the arms' nearest neighbours then."""

    tick: int
    orders: list[Order]
    separations: list[NearestPair]
