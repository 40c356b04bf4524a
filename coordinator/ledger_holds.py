"""The ledger's holds: a denied approach is no attempt at the part, but holds the denied arm off it a while, so two
arms each standing in the other's way do not meet again at every decision; a part denied too often is given up."""

from __future__ import annotations

from coordinator.ledger_records import LedgerRecords
from coordinator.tasks import PartFate, PartRecord, TaskState

# a denied approach is no attempt; the arm is not given the part again for `DENIAL_HOLD_S` (it gives way meanwhile:
# an arm left standing goes home), and a part denied `MAX_DENIALS` times is given up
MAX_DENIALS = 10
DENIAL_HOLD_S = 2.0


def refused_by(part: PartRecord) -> tuple[str, ...]:
    """The arms a task for the part may not be given: those that cannot grasp it as it lies, those held off it."""
    return tuple(sorted(part.refused_by | {a for a, _ in part.held_off}))


def deny(part: PartRecord, arm: str, reason: str, now_s: float) -> None:
    """An approach the guard denied: no attempt, but the arm is held off the part a while (two arms each in the
    other's way would otherwise meet again at the next decision, for ever)."""
    part.denials += 1
    part.held_off = (*[(a, t) for a, t in part.held_off if a != arm], (arm, now_s + DENIAL_HOLD_S))
    if part.denials >= MAX_DENIALS and part.fate == PartFate.ON_LINE:
        part.fate, part.reason = PartFate.FAILED, f"{MAX_DENIALS} approaches denied; last: {reason}"


def release_holds(part: PartRecord, now_s: float, records: LedgerRecords) -> None:
    """Arms whose hold on the part is over may be given it again (its pending task no longer refuses them)."""
    held = tuple((a, t) for a, t in part.held_off if t > now_s)
    if held == part.held_off:
        return
    part.held_off = held
    task = records.open_task(part.part_id)
    if task is not None and task.state == TaskState.PENDING:
        task.refused_by = refused_by(part)
