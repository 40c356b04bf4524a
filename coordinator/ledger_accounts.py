"""The ledger's accounts: every part's fate counted, and each part not completed listed with why."""

from __future__ import annotations

from collections import Counter

from coordinator.ledger_records import LedgerRecords
from coordinator.tasks import PartFate, TaskState


def totals(records: LedgerRecords, buffers: frozenset[str]) -> dict:
    """The run's counts of parts by fate and of tasks by outcome (`buffers`: the line's buffer stations)."""
    fates = Counter(p.fate.value for p in records.parts.values())
    tasks = records.tasks.values()
    return {
        "parts_spawned": len(records.parts),
        "parts_completed": fates[PartFate.COMPLETED.value],
        "parts_missed": fates[PartFate.MISSED.value],
        "parts_failed": fates[PartFate.FAILED.value],
        "parts_in_progress": fates[PartFate.ON_LINE.value],
        "tasks_done": sum(t.state == TaskState.DONE for t in tasks),
        "tasks_failed": sum(t.state == TaskState.FAILED for t in tasks),
        "parts_buffered": sum(t.state == TaskState.DONE and t.target in buffers for t in tasks),
    }


def unfinished(records: LedgerRecords) -> list[dict]:
    """Each part not completed, with its fate and why: nothing is silently dropped from a summary."""
    return [
        {"part_id": p.part_id, "fate": p.fate.value, "location": p.location, "reason": p.reason}
        for p in records.parts.values()
        if p.fate != PartFate.COMPLETED
    ]
