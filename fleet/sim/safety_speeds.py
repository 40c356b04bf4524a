"""How fast two arms could close the gap between them: the bounds the plant's safety layer steps its walk by.

A point of an arm moves at most sum_j |dq_j| * lever_j (`coordinator.geometry.ArmGeometry.joint_levers_m`). Each
committed path's bound is sampled once on a grid of absolute sim time (`GRID_DT_S`), at the path's own times
clipped to its span (so a path that starts between two grid points is bounded by its speed at its start), and kept
while the path is: a goal's check then adds its neighbours' bounds by slicing, not by evaluating their splines.
"""

from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np

from robots.joint_trajectory import Spline

GRID_DT_S = 0.02  # the grid the bounds are sampled on (absolute sim time)
WINDOW_SLACK = 1.25  # a window's speed may pass the larger of its ends' by this factor
WINDOW_FLOOR = 0.05  # ... and by this share of the path's peak (a window whose ends are both near rest)
KEPT_PATHS = 256  # paths whose bounds are kept (the committed ones of a line, and a few just replaced)


def grid_steps(t0_s: float, t_end_s: float) -> tuple[int, int]:
    """The grid steps k (times k * GRID_DT_S) from the last at or before `t0_s` to the first at or after `t_end_s`."""
    return math.floor(t0_s / GRID_DT_S + 1e-9), math.ceil(t_end_s / GRID_DT_S - 1e-9)


class PathSpeeds:
    """Each path's point-speed bound and joint positions on the grid, computed once per path and arm."""

    def __init__(self, levers_m: dict[str, np.ndarray]) -> None:
        self.levers_m = levers_m
        self._kept: OrderedDict[int, tuple[Spline, int, np.ndarray, np.ndarray]] = OrderedDict()

    def _sampled(self, arm: str, spline: Spline) -> tuple[Spline, int, np.ndarray, np.ndarray]:
        kept = self._kept.get(id(spline))
        if kept is not None and kept[0] is spline:
            return kept
        k0, k1 = grid_steps(spline.t0_s, spline.moves_until_s)  # a held tail rests: no bound, its end's joints
        times = np.clip(np.arange(k0, k1 + 1) * GRID_DT_S, spline.t0_s, spline.moves_until_s)
        speeds = np.abs(np.asarray(spline.dpoly(times), float)) @ self.levers_m[arm]
        positions = np.asarray(spline.poly(times), float)
        kept = self._kept[id(spline)] = (spline, k0, speeds, positions)
        if len(self._kept) > KEPT_PATHS:
            self._kept.popitem(last=False)
        return kept

    def of(self, arm: str, spline: Spline) -> tuple[int, np.ndarray]:
        """The first grid step of `spline`'s bound and the bound at each step from there to its end."""
        return self._sampled(arm, spline)[1:3]

    def q_at_step(self, arm: str, spline: Spline, k: int) -> np.ndarray | None:
        """`spline`'s joints at grid step k (exact: the spline evaluated there), None off its grid span."""
        _, k0, _, positions = self._sampled(arm, spline)
        return positions[k - k0] if 0 <= k - k0 < len(positions) else None

    def on(self, arm: str, splines: list[Spline], ka: int, kb: int) -> np.ndarray:
        """The sum of `splines`' bounds at grid steps ka..kb (0 where a path does not reach)."""
        out = np.zeros(kb - ka + 1)
        for spline in splines:
            k0, speeds = self.of(arm, spline)
            lo, hi = max(ka, k0), min(kb, k0 + speeds.size - 1)
            if lo <= hi:
                out[lo - ka : hi - ka + 1] += speeds[lo - k0 : hi - k0 + 1]
        return out


class Closing:
    """How far two arms could close their gap from a goal's start on: an upper bound on the distance their points
    can travel, cumulated over the grid (each window bounded by its ends' speeds, with slack)."""

    def __init__(self, grid_s: np.ndarray, point_speeds: np.ndarray) -> None:
        peak = float(point_speeds.max(initial=0.0))
        window = np.maximum(point_speeds[:-1], point_speeds[1:]) * WINDOW_SLACK + peak * WINDOW_FLOOR
        self.grid_s, self.window = grid_s, window
        self.travel = np.concatenate([[0.0], np.cumsum(window * np.diff(grid_s))])

    def time_to_close(self, t_s: float, gap_m: float) -> float:
        """The earliest time after `t_s` the two could have closed `gap_m` (inf: not before both rest)."""
        target = float(np.interp(t_s, self.grid_s, self.travel)) + gap_m
        k = int(np.searchsorted(self.travel, target, side="left"))
        if k >= self.travel.size:
            return math.inf
        if k == 0:
            return t_s
        return float(self.grid_s[k - 1] + (target - self.travel[k - 1]) / max(self.window[k - 1], 1e-12))
