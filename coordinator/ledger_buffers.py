"""The ledger's buffers: a belt part is set down on a free buffer (`Station.buffer`) when it would otherwise be lost,
and goes on from there once its station is ready. Two cases: the part itself is about to ride off while its next
station is not ready; or its fixture is taken and more parts for it ride behind, so that the arm sent to hold it at
the fixture's edge would let them ride off."""

from __future__ import annotations

from collections.abc import Callable

from coordinator.ledger_records import LedgerRecords
from coordinator.ledger_stations import StationTurns, other_stations
from coordinator.tasks import CONVEYOR, TAKEN_STATES, PartFate, PartRecord, Task, TaskState
from scenes.schema import Scene

# the buffers an arm able to bring a part to a station also reaches (the dispatcher knows the arms' reach)
BuffersNear = Callable[[str], tuple[str, ...]]
# whether a belt part soon rides past the last point an arm able to set it on a buffer reaches (the dispatcher knows
# the belt): (part, buffer) -> bool
SoonLost = Callable[[PartRecord, str], bool]


class Buffering:
    """Which part goes to a buffer (`Station.buffer`), and back to its route, from `records` and the stations'
    `turns`."""

    def __init__(self, records: LedgerRecords, turns: StationTurns, scene: Scene) -> None:
        self.records = records
        self.turns = turns
        self.scene = scene
        self.buffers = frozenset(scene.buffers())  # asked about each refresh, so worked out once

    def review(self, part: PartRecord, behind: list[PartRecord], near: BuffersNear | None) -> None:
        """A part's open task looked at again: withdrawn if it went stale (`StationTurns.withdraw_if_stale`), else
        to a buffer or back (`rebuffer`)."""
        task = self.records.open_task(part.part_id)
        if task is not None:
            self.turns.withdraw_if_stale(task, part)
            if self.buffers and task.task_id in self.records.tasks:
                self.rebuffer(task, part, behind, near)

    def rebuffer(self, task: Task, part: PartRecord, behind: list[PartRecord], near: BuffersNear | None) -> None:
        """A pending belt task to a fixture goes to a free buffer near it while `_better_buffered`, and back once
        not; a pending task to a buffer whose part's station became ready for it goes straight there. An arm that
        took the task keeps it."""
        station = part.next_station
        if task.state != TaskState.PENDING or part.location != CONVEYOR or station is None:
            return
        if task.target in self.buffers:
            if self.turns.ready(part, station) and not self.better_buffered(part, station, behind, near, task):
                task.go_to(station, other_stations(self.scene, part))
            elif not (free := self.free_buffers(besides=task)):  # another task took its buffers meanwhile
                self.records.drop(task)
            else:  # only buffers still free (another task may have taken one of its alternatives)
                target = task.target if task.target in free else free[0]
                task.go_to(target, tuple(b for b in free if b != target))
        elif (free := self.better_buffered(part, station, behind, near, task)) and task.target == station:
            task.go_to(free[0], free[1:])

    def in_turn(self) -> list[PartRecord]:
        """The parts in the order they are given tasks: as they arrived, but the parts resting on buffers after the
        others (they can wait; a belt part cannot). Measured: letting a buffered part go first unless a belt part
        was about to ride off (8 s) lost more belt parts on handover (4 seeds: 8 missed against 3)."""
        parts = list(self.records.parts.values())
        return sorted(parts, key=lambda p: p.location in self.buffers) if self.buffers else parts

    def buffer_for(self, part: PartRecord, soon_lost: SoonLost | None) -> tuple[str, ...]:
        """The free buffers (nothing resting there, nothing on its way) a belt part is about to ride past the last
        chance to be set down on, in scene order; none if there are none."""
        if not self.buffers or part.location != CONVEYOR or soon_lost is None:
            return ()
        return tuple(b for b in self.free_buffers() if soon_lost(part, b))

    def free_buffers(self, besides: Task | None = None) -> tuple[str, ...]:
        """The buffers with nothing resting there and no part on its way there (but `besides`'s), in scene order."""
        empty = (b for b in self.scene.buffers() if not self.turns.occupants(b))
        return tuple(b for b in empty if all(t is besides for t in self.records.inbound(b)))

    def waiting_on_belt(self) -> list[PartRecord]:
        """The belt parts no arm has been given yet (worked out once a refresh, for `better_buffered`)."""
        taken = {t.part_id for t in self.records.open_tasks() if t.state in TAKEN_STATES}
        return [
            p
            for p in self.records.parts.values()
            if p.location == CONVEYOR and p.fate == PartFate.ON_LINE and p.part_id not in taken
        ]

    def better_buffered(
        self, part: PartRecord, station: str, behind: list[PartRecord], near: BuffersNear | None, task: Task
    ) -> tuple[str, ...]:
        """The buffers near `station`, free but for `task` (the part's own), a belt part bound for it had better go
        to (none: it had not): the part cannot enter the fixture now (pipelining would send an arm to hold it at the
        edge) and more parts for the fixture ride behind it, which the held arm could not take."""
        if near is None or not self.turns.pipelined(station) or self.turns.enterable_now(part, station):
            return ()
        if not any(p.arrived_s > part.arrived_s and p.next_station == station for p in behind):
            return ()
        near_station = near(station)
        return tuple(b for b in self.free_buffers(besides=task) if b in near_station)
