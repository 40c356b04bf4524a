"""The coordinator's part of the run summary, worked out from the dispatcher's records: the tasks, the arms still
waiting for a grant, the line's bound with this run's own arrivals and with its measured hop times."""

from __future__ import annotations

import math

from coordinator.allocation import CachedReach
from coordinator.capacity import (
    CapacityBound,
    belt_window_caps,
    capacity_bound,
    finishable_arrivals,
    measured_hop_seconds,
)
from coordinator.dispatch_book import ArmBook
from coordinator.guard import CollisionGuard
from coordinator.ledger import Ledger
from scenes.schema import Scene


def task_rows(ledger: Ledger) -> list[dict]:
    """Every task of the run, as the summary lists it."""
    return [
        {
            "task_id": t.task_id,
            "part_id": t.part_id,
            "source": t.source,
            "target": t.target,
            "state": t.state.value,
            "arm": t.arm,
            "created_s": t.created_s,
            "assigned_s": t.assigned_s,
            "deadline_s": t.deadline_s,
            "done_s": t.done_s,
            "reassignments": t.reassignments,
            "reason": t.reason,
            "failure_code": t.failure_code,
        }
        for t in ledger.tasks.values()
    ]


def grant_requests_open(
    arms: ArmBook, guard: CollisionGuard, held_now: dict[str, str], now_s: float
) -> dict[str, float]:
    """Every arm waiting for a grant, and for how long (s): a request not answered yet (but one held for a
    fixture), or one denied and asked again (`DeniedArms.waiting_s`), so an arm held by denials shows as waiting
    too."""
    waiting = {a: s for a, s in guard.denials().waiting_s(now_s).items() if a not in arms.requests}
    open_now = {a: now_s - p.t_start_s for a, p in arms.requests.items() if a not in held_now}
    return {a: round(max(s, 0.0), 3) for a, s in sorted((open_now | waiting).items())}


def run_capacity(
    scene: Scene, ledger: Ledger, reach: dict[str, CachedReach], capacity: CapacityBound, end_s: float
) -> dict | None:
    """The capacity bound with this run's own arrivals, those in time to be finished by `end_s`, in place of the
    mean rates (None before any time passed): what this run could have completed at best."""
    if end_s <= 0:
        return None
    arrived = [(p.feeder, p.type_index, p.arrived_s) for p in ledger.parts.values()]
    model = capacity.model
    counts = finishable_arrivals(scene, arrived, end_s, model)
    caps = belt_window_caps(scene, arrived, end_s, model)
    bound = capacity_bound(
        scene,
        reach=reach,
        model=model,
        arrivals_per_s={k: n / end_s for k, n in counts.items()},
        type_limits=[(f"{c.arm} belt window", c.types, c.at_most / end_s) for c in caps],
    )
    return bound.as_dict() | {
        "parts_finishable": sum(counts.values()),
        # of them, the most the run could complete (fewer where an assembly pairs them or a belt window caps them)
        "parts_completable": math.floor(bound.throughput_bound_per_min * end_s / 60.0 + 1e-6),
        "sim_seconds": round(end_s, 3),
        "belt_windows": {c.arm: {"parts": c.arrived, "at_most": c.at_most} for c in caps},
    }


def measured_capacity(
    scene: Scene, ledger: Ledger, reach: dict[str, CachedReach], capacity: CapacityBound
) -> dict | None:
    """The capacity bound again with the hop times this run measured (None before any task was done)."""
    measured = measured_hop_seconds(list(ledger.tasks.values()))
    if not measured:
        return None
    return capacity_bound(scene, measured, reach, capacity.model).as_dict() | {
        "measured_hop_s": {
            f"{arm}: {source} -> {target}": round(s, 3) for (arm, source, target), s in sorted(measured.items())
        }
    }
