"""The ledger's buffers: a belt part about to ride off while its next station is not ready is set down on a free
buffer (`Station.buffer`), and goes on from there once the station is ready."""

from __future__ import annotations

from collections.abc import Callable

from coordinator.tasks import CONVEYOR, PartRecord, Task, TaskState


class LedgerBuffers:
    """Which part goes to a buffer, and back to its route: one concern of `Ledger` (it shares the ledger's records)."""

    def _unbuffer(self, task: Task, part: PartRecord) -> None:
        """A pending task to a buffer whose part's next station became ready before an arm took it goes straight
        there instead."""
        if task.state != TaskState.PENDING or task.target not in self.buffers or part.next_station is None:
            return  # (a buffer is on no route: a task to one is a detour)
        if self._ready(part, part.next_station):
            task.go_to(part.next_station, self._other_stations(part))

    def _buffer_for(self, part: PartRecord, soon_lost: Callable[[PartRecord], bool] | None) -> str | None:
        """A free buffer for a belt part about to be lost (nothing resting there, nothing on its way), or None."""
        if not self.buffers or part.location != CONVEYOR or soon_lost is None:
            return None
        free = [b for b in self.scene.buffers() if not self._occupants(b) and not self._inbound(b)]  # scene order
        return free[0] if free and soon_lost(part) else None
