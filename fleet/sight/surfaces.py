"""The surfaces of a line as perception needs them: the velocity of the surface under a point (a part on the belt
rides it), and whether a part can be lying at a point or is in the air, in a claw."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from scenes.schema import Scene

TOP_BAND_SPARE_M = 0.02  # a part on the belt has its top face at most its height and this above the belt's surface


def belt_velocity_at(scene: Scene) -> Callable[[np.ndarray], np.ndarray]:
    """The surface velocity under a world point: the conveyor's over its belt (a part lying on it rides it; one
    lifted above it, in a claw, does not), else 0."""
    belt = scene.conveyor
    if belt is None or belt.speed_m_per_s == 0.0:
        return lambda point: np.zeros(3)
    c, s = math.cos(belt.pose.yaw_rad), math.sin(belt.pose.yaw_rad)
    x0, y0, z0 = belt.pose.xyz
    velocity = np.asarray(belt.direction) * belt.speed_m_per_s
    band_m = max((p.size_m[2] for f in scene.feeders for p in f.parts), default=0.0) + TOP_BAND_SPARE_M

    def at(point: np.ndarray) -> np.ndarray:
        dx, dy = point[0] - x0, point[1] - y0
        along, across = c * dx + s * dy, -s * dx + c * dy
        on = 0.0 <= along <= belt.length_m and abs(across) <= belt.width_m / 2 and point[2] <= z0 + band_m
        return velocity if on else np.zeros(3)

    return at


def rests_at(scene: Scene) -> Callable[[np.ndarray], bool]:
    """Whether a part whose top face is at a world point can be lying on something: at most two part heights above
    the highest surface of the line (the belt, a station's top); higher, it is in the air, in a claw."""
    tallest_m = max((p.size_m[2] for f in scene.feeders for p in f.parts), default=0.0)
    tops = [s.pose.xyz[2] + s.size_m[2] for s in scene.stations]
    if scene.conveyor is not None:
        tops.append(scene.conveyor.pose.xyz[2])
    ceiling_m = max(tops, default=0.0) + 2 * tallest_m + TOP_BAND_SPARE_M
    return lambda point: point[2] <= ceiling_m
