"""Filling a scene's reach tables ahead of its runs (`fleet reach`): every cell its decisions ask of each arm
(`coordinator.reach_cells`), worked out on all cores in chunks and added to each arm's table on disk."""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import signal
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from coordinator.reach_cache import GRID_M, CachedReach, Cell
from coordinator.reach_cells import scene_cells
from coordinator.reach_table import save_reach
from scenes.schema import Arm, Scene

CHUNK_CELLS = 400  # cells a worker works out before it writes them and takes more


@dataclass(frozen=True)
class ArmFill:
    """What a fill found for one arm: the cells a run asks of it, how many its table lacked, how many it reaches."""

    arm: str
    cells: int
    missing: int
    reached: int = 0


def _quiet() -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle: it stops the pool


def _fill_chunk(arm: Arm, cells: list[Cell]) -> tuple[str, int]:
    reach = CachedReach.of(arm)
    reached = sum(reach.answer(c) is not None for c in cells)
    save_reach([reach])
    return arm.name, reached


def missing_cells(scene: Scene) -> dict[str, tuple[Arm, list[Cell], int]]:
    """Per arm: the arm, the cells its table lacks, and how many cells a run asks of it."""
    out = {}
    for arm in scene.arms:
        reach = CachedReach.of(arm)
        known, top_down = reach.answers(), reach.top_down
        cells = [c for c in scene_cells(scene, arm) if not top_down.beyond(np.array(c) * GRID_M)]  # no IK past reach
        out[arm.name] = (arm, [c for c in cells if c not in known], len(cells))
    return out


def fill_tables(scene: Scene, jobs: int, on_chunk: Callable[[int], None] | None = None) -> list[ArmFill]:
    """Work out every cell the scene's arms lack, `jobs` processes at a time; `on_chunk(cells)` after each chunk."""
    todo = missing_cells(scene)
    chunks = [
        (arm, cells[k : k + CHUNK_CELLS]) for arm, cells, _ in todo.values() for k in range(0, len(cells), CHUNK_CELLS)
    ]
    reached = {name: 0 for name in todo}
    context = multiprocessing.get_context("spawn")  # nothing of this process's Pinocchio or BLAS state is shared
    with concurrent.futures.ProcessPoolExecutor(max(1, jobs), mp_context=context, initializer=_quiet) as pool:
        futures = {pool.submit(_fill_chunk, arm, cells): len(cells) for arm, cells in chunks}
        try:
            for future in concurrent.futures.as_completed(futures):
                name, hits = future.result()
                reached[name] += hits
                if on_chunk is not None:
                    on_chunk(futures[future])
        except BaseException:
            pool.shutdown(wait=True, cancel_futures=True)
            raise
    return [ArmFill(name, total, len(cells), reached[name]) for name, (_, cells, total) in todo.items()]
