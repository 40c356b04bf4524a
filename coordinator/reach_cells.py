"""The reach cells a line's decisions ask of an arm: over the belt at each part type's pick height, over each
station's surface and the parts resting on it, within the arm's reach. What `fleet reach` fills ahead."""

from __future__ import annotations

import math

import numpy as np

from coordinator.allocation import HOVER_M
from coordinator.reach_cache import GRID_M, Cell
from robots.measured_reach import reach_m_of
from robots.registry import get_robot
from scenes.schema import Arm, Scene

REST_SLACK_M = 0.004  # a part at rest sits a little lower or higher than its nominal height (either grid cell)
EDGE_M = 0.02  # a part's centre may lie this far past the belt's or a station's edge (jitter, a part half over)


def _heights(z_m: float) -> set[int]:
    return {round((z_m - REST_SLACK_M) / GRID_M), round((z_m + REST_SLACK_M) / GRID_M)}


def _rectangle(centre_xy, yaw_rad: float, along_m: float, across_m: float, along_from_m: float = 0.0) -> np.ndarray:
    """Grid points (x, y) covering a rectangle `along_m` x `across_m`, from `along_from_m` along its yaw (centred
    across), `EDGE_M` wider every way."""
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    along = np.arange(along_from_m - EDGE_M, along_from_m + along_m + EDGE_M + GRID_M / 2, GRID_M / 2)
    across = np.arange(-across_m / 2 - EDGE_M, across_m / 2 + EDGE_M + GRID_M / 2, GRID_M / 2)
    a, b = np.meshgrid(along, across, indexing="ij")
    x = centre_xy[0] + c * a.ravel() - s * b.ravel()
    y = centre_xy[1] + s * a.ravel() + c * b.ravel()
    return np.unique(np.round(np.stack([x, y], axis=1) / GRID_M).astype(int), axis=0)


def scene_cells(scene: Scene, arm: Arm) -> list[Cell]:
    """The cells `arm`'s reach is asked in a run of `scene` (belt, stations), sorted; farther than its declared
    reach (`reach_m_of`) from its base none are asked (answered "no" without IK)."""
    part_heights = {p.size_m[2] for f in scene.feeders for p in f.parts}
    found: set[Cell] = set()
    conveyor = scene.conveyor
    if conveyor is not None:
        on_belt = {p.size_m[2] for f in scene.feeders if f.into == "conveyor" for p in f.parts}
        xy = _rectangle(conveyor.pose.xyz[:2], conveyor.pose.yaw_rad, conveyor.length_m, conveyor.width_m)
        for h in on_belt:
            for z in _heights(conveyor.pose.xyz[2] + h / 2 + HOVER_M):
                found.update((int(x), int(y), z) for x, y in xy)
    for station in scene.stations:
        xy = _rectangle(
            station.pose.xyz[:2], station.pose.yaw_rad, station.size_m[0], station.size_m[1], -station.size_m[0] / 2
        )
        resting = {h / 2 for h in part_heights}
        if station.kind == "fixture":  # a layer on the layer below
            resting |= {below + h / 2 for below in part_heights for h in part_heights}
        for z_m in [station.surface_z_m + HOVER_M, *(station.surface_z_m + r + HOVER_M for r in resting)]:
            for z in _heights(z_m):
                found.update((int(x), int(y), z) for x, y in xy)
    base, reach = np.asarray(arm.base.xyz[:2]), reach_m_of(get_robot(arm.model))
    return sorted(c for c in found if math.hypot(c[0] * GRID_M - base[0], c[1] * GRID_M - base[1]) <= reach)
