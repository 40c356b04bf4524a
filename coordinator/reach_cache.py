"""Whether (and with which joints) an arm points its claw straight down at a spot: Pinocchio IK on a 1 cm grid,
each cell's answer a function of the cell alone.

A new cell is solved from the answer of its parent, the cell at its height on the next coarser lattice (4 cm, then
16 cm) next to it: one quick solve, a few ms (else quick solves a cell apart along the way), where the full search
(every tilt, restarts) takes 100+ ms for a short arm that must lean. Only a cell whose parent is out of reach, or
whose walk from it does not converge, is searched in full.
Since no answer depends on which cells were asked before, a table filled by another run, in another order, or ahead
of time (`coordinator.reach_table`), gives every decision the same answer it would have worked out itself.
"""

from __future__ import annotations

import atexit
import math
import time
from pathlib import Path

import numpy as np

from coordinator.reach_table import read_table, save_reach, table_key, table_path
from robots.frames import yaw_transform
from robots.ik import IKOptions
from robots.measured_reach import reach_m_of
from robots.registry import get_robot
from robots.top_down import TopDownIK
from scenes.schema import Arm

GRID_M = 0.01
LATTICE_CELLS = (16, 4, 1)  # coarsest first: a cell's parent is the nearest cell of the next coarser lattice
REACH_IK = IKOptions(restarts=8)  # a reach check must not miss a reachable spot for an unlucky start

Cell = tuple[int, int, int]
Answer = tuple[float, np.ndarray] | None  # (tilt_rad, arm joints), or None: out of reach


_SHARED: dict[str, CachedReach] = {}  # by table key: the reaches `CachedReach.of` gave out in this process
_PLACED: dict[tuple, str] = {}  # (robot, its declaration's id, base xyz, yaw) -> table key, as first worked out


def save_shared() -> int:
    """Write what this process's shared reaches worked out to their tables (at exit, and by nodes that leave
    without running exit handlers); returns the cells written."""
    return save_reach(list(_SHARED.values()))


def parent_cell(cell: Cell) -> Cell | None:
    """The cell a cell is first solved from: the nearest at its height on the next coarser lattice (None for a cell
    of the coarsest, which is searched in full). Heights are not coarsened: how far a short arm must lean changes
    with the height, so a cell above or below is a poor start."""
    x, y, z = cell
    for coarser, finer in zip(LATTICE_CELLS, LATTICE_CELLS[1:]):
        if x % finer == 0 and y % finer == 0:
            if x % coarser == 0 and y % coarser == 0:
                continue
            return (coarser * math.floor(x / coarser + 0.5), coarser * math.floor(y / coarser + 0.5), z)
    return None


def cell_of(point) -> Cell:
    """The grid cell of a world point (plain floats: numpy scalars cost more here)."""
    x, y, z = (point.tolist() if isinstance(point, np.ndarray) else [float(v) for v in point])[:3]
    return (round(x / GRID_M), round(y / GRID_M), round(z / GRID_M))


class CachedReach:
    """One arm's reach, cell by cell (see the module's docstring); `search_s` is the wall time spent working out
    cells asked the first time (what a plug-in allocator is not charged for)."""

    search_s: float = 0.0  # class defaults: older pickles
    table_path: Path | None = None  # the table on disk this reach was read from and is saved to (None: no table)

    def __init__(self, top_down: TopDownIK, table_path: Path | None = None) -> None:
        self.top_down = top_down
        self.velocity_limit = top_down.km.arm_velocity_limit
        self.table_path = table_path
        self._cache: dict[Cell, Answer] = read_table(table_path)
        self.worked_out: set[Cell] = set()  # cells this object solved (not read from a table): what a table lacks

    @classmethod
    def of(cls, arm: Arm, shared: bool = True) -> CachedReach:
        """The reach of a scene's arm where it stands (its robot model, the reach checks' IK options). `shared`: the
        one this process holds for that placement, first read from its table on disk (`coordinator.reach_table`) and
        written back when the process exits (answers depend on the cell alone, so every user may share them)."""
        spec = get_robot(arm.model)
        placement = (arm.model, id(spec), tuple(arm.base.xyz), arm.base.yaw_rad)
        if shared and placement in _PLACED:  # an env's every reset asks again: no model built, nothing hashed
            return _SHARED[_PLACED[placement]]
        top_down = TopDownIK(
            spec, yaw_transform(arm.base.xyz, arm.base.yaw_rad), options=REACH_IK, reach_m=reach_m_of(spec)
        )
        if not shared:
            return cls(top_down)
        key = _PLACED[placement] = table_key(top_down, (GRID_M, LATTICE_CELLS))
        if key not in _SHARED:
            if not _SHARED:
                atexit.register(save_shared)
            _SHARED[key] = cls(top_down, table_path(top_down.spec.uid, key))
        return _SHARED[key]

    def __getstate__(self) -> dict:
        """What a snapshot keeps: the cells worked out here, not the table's (read again on restore; a cell's answer
        is its own, so one worked out again is the same)."""
        state = dict(vars(self))
        state["_cache"] = {c: self._cache[c] for c in getattr(self, "worked_out", ()) if c in self._cache}
        return state

    def __setstate__(self, state: dict) -> None:
        vars(self).update(state)
        self._cache = read_table(self.table_path) | state["_cache"]

    def joints(self, point) -> np.ndarray | None:
        key = cell_of(point)
        found = self._cache[key] if key in self._cache else self._timed(key)
        return None if found is None else found[1]

    def __call__(self, point) -> bool:
        return self.joints(point) is not None

    def answer(self, cell: Cell) -> Answer:
        """The cell's (tilt, joints), or None: from the cache, else worked out now."""
        return self._cache[cell] if cell in self._cache else self._timed(cell)

    def answers(self) -> dict[Cell, Answer]:
        """Every cell known so far (a copy)."""
        return dict(self._cache)

    def _timed(self, cell: Cell) -> Answer:
        started = time.perf_counter()
        found = self._solve(cell)
        if cell in getattr(self, "worked_out", ()):  # not a cell past the reach: "no" without IK, nothing worked out
            self.search_s += time.perf_counter() - started
        return found

    def _walk(self, start: np.ndarray, spot: np.ndarray, answer: tuple[float, np.ndarray]) -> Answer:
        """The spot reached from a reached one nearby at its tilt: one quick solve, else quick solves a cell apart
        along the straight line between them (each from the last); None if one does not converge."""
        tilt, q = answer
        direct = self.top_down.joints_near(spot, tilt, q)
        if direct is not None:
            return tilt, direct
        steps = math.ceil(float(np.abs(spot - start).max()) / GRID_M)
        for k in range(1, steps + 1):
            q = self.top_down.joints_near(start + (spot - start) * (k / steps), tilt, q)
            if q is None:
                return None
        return tilt, q

    def _solve(self, cell: Cell) -> Answer:
        spot = np.array(cell, float) * GRID_M
        if self.top_down.beyond(spot):  # past the measured reach: "no" without IK, nothing a table need keep
            self._cache[cell] = None
            return None
        found = None
        parent = parent_cell(cell)
        if parent is not None:
            above = self._cache[parent] if parent in self._cache else self._solve(parent)
            if above is not None:
                found = self._walk(np.array(parent, float) * GRID_M, spot, above)
        if found is None:
            found = self.top_down.reach_pose(spot)
        self._cache[cell] = found
        if not hasattr(self, "worked_out"):  # read back from an older snapshot
            self.worked_out = set()
        self.worked_out.add(cell)
        return found
