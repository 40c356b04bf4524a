"""Timings of the coordinator's hot paths: a full-cell separation check, a grant check, an allocation.

Pure computation (no bus, no physics), so the figures are what the coordinator
process spends per decision.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from coordinator.allocation import assign_min_cost
from coordinator.geometry import ArmGeometry
from coordinator.guard import CollisionGuard, TimedPath
from robots.frames import yaw_transform
from robots.registry import get_robot


def _timed(fn, repeats: int) -> float:
    """Median seconds of `fn()` over `repeats` calls."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return float(np.median(times))


def row_of_arms(n: int, spacing_m: float = 0.55) -> CollisionGuard:
    """`n` OpenClaw arms in a row, as on the sorting line."""
    spec = get_robot("openclaw")
    return CollisionGuard(
        {
            f"arm_{i}": ArmGeometry(f"arm_{i}", spec, yaw_transform((i * spacing_m, -0.35, 0.0), np.pi / 2))
            for i in range(n)
        }
    )


@dataclass(frozen=True)
class CollisionRow:
    arms: int
    separation_ms: float  # every pair's distance, arms already placed
    place_and_separation_ms: float  # every arm moved to a new configuration first (FK + FCL update)
    grant_ms: float  # one 2 s path of arm_0 against all others
    grant_samples: int


def bench_collision(arms: int, repeats: int = 50, seed: int = 0) -> CollisionRow:
    guard = row_of_arms(arms)
    rng = np.random.default_rng(seed)
    home = np.asarray(get_robot("openclaw").home_q)
    configs = [{a: home + rng.uniform(-0.3, 0.3, 6) for a in guard.arms} for _ in range(repeats)]
    guard.min_separation(configs[0])
    separation = _timed(lambda: guard.min_separation(configs[0]), repeats)
    it = iter(configs * 2)
    placed = _timed(lambda: guard.min_separation(next(it)), repeats)
    path = TimedPath("arm_0", tuple(home), tuple(home + np.array([0.8, 0.4, -0.3, 0.0, 0.3, 0.0])), 0.0, 2.0)
    grant = _timed(lambda: guard.check(path), max(5, repeats // 5))
    return CollisionRow(arms, separation * 1e3, placed * 1e3, grant * 1e3, guard.last_check_samples)


@dataclass(frozen=True)
class AllocationRow:
    tasks: int
    arms: int
    solve_ms: float


def bench_allocation(tasks: int, arms: int = 8, repeats: int = 20, seed: int = 0) -> AllocationRow:
    """`linear_sum_assignment` on a tasks x arms cost matrix with a quarter of the pairs infeasible."""
    rng = np.random.default_rng(seed)
    cost = rng.uniform(2.0, 20.0, size=(tasks, arms))
    cost[rng.random((tasks, arms)) < 0.25] = np.inf
    return AllocationRow(tasks, arms, _timed(lambda: assign_min_cost(cost), repeats) * 1e3)


@dataclass(frozen=True)
class DecisionRow:
    allocator: str
    arms: int
    pending: int
    decisions: int
    p50_ms: float
    p99_ms: float


def bench_decisions(arms: int = 12, pending: int = 50, decisions: int = 200, seed: int = 0) -> list[DecisionRow]:
    """Whole decisions of each built-in allocator on the sorting line with `arms` arms, every one free, and `pending`
    belt parts riding on (each decision 0.1 s later: the coordinator's rate): reach, time costs and the solve, as the
    coordinator spends them. The first `decisions // 5` fill the reach caches and are not counted."""
    from coordinator.allocation import ALLOCATORS, ArmView, CachedReach, PartView, make_allocator
    from coordinator.ledger import Ledger
    from fleet.common.scene_loading import load_checked_scene

    scene = load_checked_scene("sorting_line", arms=arms)
    rng = np.random.default_rng(seed)
    xs = [a.base.xyz[0] for a in scene.arms]
    views = [ArmView(a.name, a.base.xyz, True, CachedReach.of(a), tuple(get_robot(a.model).home_q)) for a in scene.arms]
    ledger, start = Ledger(scene), {}
    kinds = len(scene.feeder("mixed").parts)
    for pid in range(pending):
        start[pid] = np.array([rng.uniform(min(xs) - 0.3, max(xs)), rng.uniform(-0.03, 0.03), 0.095])
        ledger.arrived(pid, "mixed", int(rng.integers(kinds)), 0.0)
    tasks, speed = ledger.refresh(0.0), np.array([scene.conveyor.speed_m_per_s, 0.0, 0.0])
    rows = []
    for name in ALLOCATORS:
        allocator, times = make_allocator(name, scene), []
        for k in range(decisions):
            parts = {pid: PartView(p + speed * 0.1 * k, speed) for pid, p in start.items()}
            began = time.perf_counter()
            allocator.allocate(tasks, views, parts, set())
            if k >= decisions // 5:
                times.append(time.perf_counter() - began)
        ms = np.array(times) * 1e3
        rows.append(DecisionRow(name, arms, pending, len(times), float(np.median(ms)), float(np.percentile(ms, 99))))
    return rows
