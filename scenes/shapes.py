"""The static solids of a cell as boxes in each object's own frame: one description for the physics and the monitor.

A box is `(centre_xyz, half_size_xyz)` in metres, in the frame of its station
(or of the belt's start), which stands at the object's `pose` (position, yaw).
"""

from __future__ import annotations

from scenes.schema import FLOOR_M, Conveyor, Station

Box = tuple[tuple[float, float, float], tuple[float, float, float]]
BELT_DEPTH_M = 0.04
WALL_M = FLOOR_M


def station_boxes(s: Station) -> list[Box]:
    """A fixture is one block; a bin or tray is a floor plate and four walls (a tray's walls at most 2 cm high)."""
    sx, sy, sz = s.size_m
    if s.kind == "fixture":
        return [((0.0, 0.0, sz / 2), (sx / 2, sy / 2, sz / 2))]
    h = sz if s.kind == "bin" else min(sz, 0.02)
    return [
        ((0.0, 0.0, WALL_M / 2), (sx / 2, sy / 2, WALL_M / 2)),
        ((sx / 2 - WALL_M / 2, 0.0, h / 2), (WALL_M / 2, sy / 2, h / 2)),
        ((-sx / 2 + WALL_M / 2, 0.0, h / 2), (WALL_M / 2, sy / 2, h / 2)),
        ((0.0, sy / 2 - WALL_M / 2, h / 2), (sx / 2, WALL_M / 2, h / 2)),
        ((0.0, -sy / 2 + WALL_M / 2, h / 2), (sx / 2, WALL_M / 2, h / 2)),
    ]


def belt_box(c: Conveyor) -> Box:
    """The belt slab, its top surface at the conveyor pose's height."""
    return ((c.length_m / 2, 0.0, -BELT_DEPTH_M / 2), (c.length_m / 2, c.width_m / 2, BELT_DEPTH_M / 2))
