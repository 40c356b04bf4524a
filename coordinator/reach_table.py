"""Reach answers kept on disk, one file per arm placement: what one run worked out, every later run reads.

Each cell's answer is a function of the cell alone (`coordinator.reach_cache`), so a table filled by any run, in any
order, gives the same decisions; the file's name holds a hash of everything an answer depends on (the robot's
declaration and URDF, where the arm stands, the IK options and code, the grid, the numerical libraries), so a
changed input finds a file of its own. `CLAWFLEET_CACHE_DIR` says where the tables live (`robots.disk_cache`: default
`$XDG_CACHE_HOME/clawfleet/reach`); `off` keeps nothing on disk.
"""

from __future__ import annotations

import fcntl
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from robots.disk_cache import cache_dir, declaration_key, replace_atomically
from robots.top_down import TopDownIK

# the modules whose code an answer depends on: a change to any of them is a new table
ANSWERED_BY = (
    "coordinator.reach_cache",
    "robots.top_down",
    "robots.ik",
    "robots.chain_span",
    "robots.kinematics",
    "robots.frames",
)


def tables_dir() -> Path | None:
    """Where reach tables are kept, or None when `CLAWFLEET_CACHE_DIR=off`."""
    return cache_dir("reach")


def table_key(top_down: TopDownIK, grid: tuple) -> str:
    """A hash of everything a cell's answer depends on."""
    return declaration_key(
        top_down.spec,
        ANSWERED_BY,
        top_down.reach_m,
        np.asarray(top_down.base_to_world, float),
        (top_down.options, grid),
    )


def table_path(robot: str, key: str) -> Path | None:
    """The file of a robot's table with this key (None when tables are off)."""
    folder = tables_dir()
    return None if folder is None else folder / f"{robot}-{key}.npz"


def read_table(path: Path | None) -> dict:
    """The cells a table file holds ({} when there is none, or it cannot be read: a table is only ever a cache)."""
    if path is None or not path.exists():
        return {}
    try:
        with np.load(path) as data:
            cells, tilts, qs = data["cells"], data["tilt_rad"], data["q"]
    except (OSError, ValueError, KeyError, EOFError):
        return {}
    return {tuple(map(int, c)): (None if np.isnan(t) else (float(t), q.copy())) for c, t, q in zip(cells, tilts, qs)}


def write_table(path: Path, answers: dict, dof: int) -> None:
    """Write `answers` merged with what the file holds now (another run may have added to it meanwhile), under a
    lock, replacing the file in one step so a reader never sees half of it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        merged = read_table(path) | answers
        cells = np.array(sorted(merged), dtype=np.int32).reshape(-1, 3)
        tilts = np.array([np.nan if merged[c] is None else merged[c][0] for c in map(tuple, cells.tolist())])
        qs = np.array([np.full(dof, np.nan) if merged[c] is None else merged[c][1] for c in map(tuple, cells.tolist())])
        replace_atomically(
            path, lambda f: np.savez(f, cells=cells, tilt_rad=tilts, q=qs.reshape(len(cells), dof)), ".npz.tmp"
        )


def save_reach(reaches: Iterable) -> int:
    """Add the cells these `CachedReach`es worked out to their arms' tables; returns how many cells were new to this
    process's tables. A table that cannot be written is skipped (a read-only home must not fail a run)."""
    written = 0
    for reach in reaches:
        fresh = getattr(reach, "worked_out", set())
        if not fresh or reach.table_path is None:
            continue
        try:
            write_table(reach.table_path, {c: reach.answer(c) for c in fresh}, reach.top_down.spec.arm_dof)
        except OSError:
            continue
        written += len(fresh)
        reach.worked_out = set()
    return written
