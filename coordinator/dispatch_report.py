"""The coordinator's part of the run summary: parts and their fates, grants, the line's bound and the run's own."""

from __future__ import annotations

import math

from coordinator.capacity import (
    belt_window_caps,
    capacity_bound,
    finishable_arrivals,
    measured_hop_seconds,
)


class DispatchReport:
    """The run summary's coordinator part: one concern of `Dispatcher`, kept apart."""

    def report(self) -> dict:
        return self.ledger.totals() | {
            "allocator": self.allocator.name,
            "allocator_faults": dict(getattr(self.allocator, "faults", {})),  # a plug-in's (`GuardedAllocator`)
            "pipeline": self.ledger.pipeline,
            "arm_events": self.losses,
            "unfinished_parts": self.ledger.unfinished(),
            "tasks": [
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
                }
                for t in self.ledger.tasks.values()
            ],
            "decisions": self.decisions,
            "grants_denied": self.guard.denied,
            "grants_given": self.grants_given,
            "tasks_reassigned": self.reassigned,
            "tasks_adopted": self.adopted,
            "grant_waits": self.guard.waits,
            "grant_requests_open": self.grant_requests_open(),
            "held_at_station_s": {a: round(s, 2) for a, s in self.held_at_station_s.items()},
            "min_separation_m": round(self.min_separation_m, 4) if math.isfinite(self.min_separation_m) else None,
            "closest_pair": list(self.closest_pair) if self.closest_pair else None,
            "capacity": self.capacity.as_dict(),
            "capacity_measured": self.measured_capacity(),
            "capacity_of_run": self.run_capacity(),
        }

    def grant_requests_open(self) -> dict[str, float]:
        """Every arm waiting for a grant, and for how long (s): a request not answered yet, or one denied and
        asked again (`DeniedArms.waiting_s`), so an arm held by denials shows as waiting too."""
        waiting = {a: s for a, s in self.guard.denials().waiting_s(self.sim_time_s).items() if a not in self.requests}
        open_now = {a: self.sim_time_s - p.t_start_s for a, p in self.requests.items() if a not in self.held_now}
        return {a: round(max(s, 0.0), 3) for a, s in sorted((open_now | waiting).items())}

    def run_capacity(self) -> dict | None:
        """The capacity bound with this run's own arrivals, those in time to be finished by now, in place of the mean
        rates (None before any time passed): what this run could have completed at best."""
        end_s = max(self.sim_time_s, self.last_event_s)
        if end_s <= 0:
            return None
        arrived = [(p.feeder, p.type_index, p.arrived_s) for p in self.ledger.parts.values()]
        model = self.capacity.model
        counts = finishable_arrivals(self.scene, arrived, end_s, model)
        caps = belt_window_caps(self.scene, arrived, end_s, model)
        bound = capacity_bound(
            self.scene,
            reach=self.reach,
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

    def measured_capacity(self) -> dict | None:
        """The capacity bound again with the hop times this run measured (None before any task was done)."""
        measured = measured_hop_seconds(list(self.ledger.tasks.values()))
        if not measured:
            return None
        return capacity_bound(self.scene, measured, self.reach, self.capacity.model).as_dict() | {
            "measured_hop_s": {
                f"{arm}: {source} -> {target}": round(s, 3) for (arm, source, target), s in sorted(measured.items())
            }
        }
