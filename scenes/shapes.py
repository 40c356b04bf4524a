"""The static solids of a cell as boxes in each object's own frame: one description for the physics and the monitor.

A box is `(centre_xyz, half_size_xyz)` in metres, in the frame of its station
(or of the belt's start), which stands at the object's `pose` (position, yaw).
"""

from __future__ import annotations

import math

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


def station_spots(s: Station, spacing_m: float, side_m: float) -> list[tuple[float, float]]:
    """World (x, y) of spots `spacing_m` apart where a part `side_m` across lies inside a station's walls (a grid
    about its centre, turned with it), nearest the centre first; at least the centre."""
    yaw = math.radians(s.pose.yaw_deg)
    c, si = math.cos(yaw), math.sin(yaw)
    per_axis = []
    for size in s.size_m[:2]:
        span = max(0.0, size - 2 * WALL_M - side_m)  # where a part's centre may lie, along this side
        n = int(span / spacing_m + 1e-9) + 1
        per_axis.append([(k - (n - 1) / 2) * spacing_m for k in range(n)])
    local = sorted(((u, v) for u in per_axis[0] for v in per_axis[1]), key=lambda uv: (uv[0] ** 2 + uv[1] ** 2, uv))
    x0, y0 = s.pose.xyz[0], s.pose.xyz[1]
    return [(x0 + c * u - si * v, y0 + si * u + c * v) for u, v in local]


def belt_box(c: Conveyor) -> Box:
    """The belt slab, its top surface at the conveyor pose's height."""
    return ((c.length_m / 2, 0.0, -BELT_DEPTH_M / 2), (c.length_m / 2, c.width_m / 2, BELT_DEPTH_M / 2))
