"""The ledger's accounts: every part's fate counted, and each part not completed listed with why."""

from __future__ import annotations

from collections import Counter

from coordinator.tasks import PartFate, TaskState


class LedgerAccounts:
    """The run's totals and unfinished parts: one concern of `Ledger` (it shares the ledger's records)."""

    def totals(self) -> dict:
        fates = Counter(p.fate.value for p in self.parts.values())
        return {
            "parts_spawned": len(self.parts),
            "parts_completed": fates[PartFate.COMPLETED.value],
            "parts_missed": fates[PartFate.MISSED.value],
            "parts_failed": fates[PartFate.FAILED.value],
            "parts_in_progress": fates[PartFate.ON_LINE.value],
            "tasks_done": sum(t.state == TaskState.DONE for t in self.tasks.values()),
            "tasks_failed": sum(t.state == TaskState.FAILED for t in self.tasks.values()),
            "parts_buffered": sum(t.state == TaskState.DONE and t.target in self.buffers for t in self.tasks.values()),
        }

    def unfinished(self) -> list[dict]:
        """Each part not completed, with its fate and why: nothing is silently dropped from a summary."""
        return [
            {"part_id": p.part_id, "fate": p.fate.value, "location": p.location, "reason": p.reason}
            for p in self.parts.values()
            if p.fate != PartFate.COMPLETED
        ]
