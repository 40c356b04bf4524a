"""The ledger's stations: stacks and assemblies at fixtures, which part may go in next, which are busy, how high a
place is."""

from __future__ import annotations

from coordinator.tasks import OPEN_STATES, TAKEN_STATES, PartFate, PartRecord, Task, TaskState


class LedgerStations:
    """The stations' stacks and turns: one concern of `Ledger`, kept apart (it shares the ledger's records)."""

    def _leave_stack(self, part: PartRecord) -> None:
        stack = self.stacks.get(part.location)
        if stack and part.part_id in stack:
            if stack[0] == part.part_id:
                stack.clear()  # the assembly moved on (or fell) as one
            else:
                stack.remove(part.part_id)

    def _ready(self, part: PartRecord, target: str, besides: Task | None = None) -> bool:
        """Precedence: an assembly layer needs the layers below it; a stack's bottom leaves only when whole.
        With pipelining, layers and parts on their way count as there (their arms wait at `may_enter`)."""
        here = self.stacks.get(part.location)
        if here is not None and part.part_id in here:
            whole = len(self.scene.station(part.location).assembles)
            if here[0] != part.part_id or (not self.pipeline and len(here) < whole):
                return False
            if self.pipeline:  # every layer placed, or an arm bringing it (a second part of one layer is not the next)
                have = {self._layer(self.parts[p], part.location) for p in here}
                have |= {
                    self._layer(self.parts[t.part_id], part.location)
                    for t in self._inbound(part.location, TAKEN_STATES)
                }
                if not set(range(whole)) <= have:
                    return False
        stack = self.stacks.get(target)
        assembles = self.scene.station(target).assembles
        if self.pipeline and target in self.gated:  # a layer below counts once an arm brings it: a task for it that
            # waits for an arm must not wait behind this one, given to the same arm (which would hold this at the edge)
            layer, coming = self._layer(part, target), self._future_layers(target, TAKEN_STATES, besides)
            return layer not in self._future_layers(target, OPEN_STATES, besides) and all(
                below in coming for below in range(layer)
            )
        if stack is not None and part.feeder in assembles:
            if len(stack) != assembles.index(part.feeder):
                return False
            if any(t.target == target for t in self.open_tasks()):
                return False  # one layer on its way at a time
        return True

    def _layer(self, part: PartRecord, station: str) -> int:
        """Where `part` goes in `station`'s stack (0, the bottom, at a station that does not assemble)."""
        assembles = self.scene.station(station).assembles
        return assembles.index(part.feeder) if part.feeder in assembles else 0

    def _inbound(self, station: str, states: tuple[TaskState, ...] = OPEN_STATES) -> list[Task]:
        """Tasks bringing a part to `station`."""
        return [t for t in self.open_tasks() if t.target == station and t.state in states]

    def _occupants(self, station: str) -> list[int]:
        """The parts resting at `station`: its stack, if it assembles; else every part there."""
        if station in self.stacks:
            return self.stacks[station]
        return [p.part_id for p in self.parts.values() if p.location == station and p.fate == PartFate.ON_LINE]

    def _future_parts(
        self, station: str, states: tuple[TaskState, ...] = OPEN_STATES, besides: Task | None = None
    ) -> list[int]:
        """The parts `station` will hold once the parts on their way (tasks in `states`, but `besides`) are there
        and the ones an arm was sent to take away are gone."""
        present = [] if self._leaving(station) else list(self._occupants(station))
        return present + [t.part_id for t in self._inbound(station, states) if t is not besides]

    def _future_layers(
        self, station: str, states: tuple[TaskState, ...] = OPEN_STATES, besides: Task | None = None
    ) -> list[int]:
        """The layers of `_future_parts`."""
        return [self._layer(self.parts[p], station) for p in self._future_parts(station, states, besides)]

    def _withdraw_if_stale(self, task: Task, part: PartRecord) -> None:
        """A pending task into a pipelined fixture that its part is no longer ready for (the layer below it was
        lost, or failed, before an arm took it) is withdrawn: an arm given it would hold its part at the edge for
        a layer that may never come, or that only it could bring."""
        if task.state == TaskState.PENDING and self.pipeline and task.target in self.gated:
            if task.target == part.next_station and not self._ready(part, task.target, besides=task):
                self._drop(task)

    def _leaving(self, station: str) -> bool:
        """What rests at `station` is whole (an assembly with every layer) and an arm was sent to take it away."""
        here, assembles = self._occupants(station), self.scene.station(station).assembles
        whole = len(here) >= len(assembles) if assembles else bool(here)  # a part taken along by a claw may lie on top
        return whole and any(t.source == station and t.state in TAKEN_STATES for t in self.open_tasks())

    def may_enter(self, task: Task, station: str) -> bool:
        """May the arm of `task` move into `station` now? Always, unless pipelining holds it: taking an assembly
        away waits until it is whole; bringing a part waits until the layers below it are placed and the parts
        before it (an assembly, a handed-over part) have been lifted off, and no arm is bringing one below it."""
        if not self.pipeline or station not in self.gated:
            return True
        assembles = self.scene.station(station).assembles
        here = self._occupants(station)
        if station == task.source:
            return not assembles or (bool(here) and here[0] == task.part_id and len(here) >= len(assembles))
        layer = self._layer(self.parts[task.part_id], station)
        if any(
            t.task_id != task.task_id and self._layer(self.parts[t.part_id], station) <= layer
            for t in self._inbound(station, TAKEN_STATES)
        ):
            return False
        return len(here) == layer

    def place_height_m(self, target: str, part_id: int | None = None) -> float:
        """Where a part's bottom goes at `target`: the station's surface, on top of any stack there (with
        pipelining, on the layers below `part_id`'s, placed or on their way, not on an assembly leaving)."""
        z = self.scene.station(target).surface_z_m
        if not (self.pipeline and target in self.gated and part_id is not None):
            return z + sum(self.parts[p].height_m for p in self.stacks.get(target, []))
        layer = self._layer(self.parts[part_id], target)
        return z + sum(
            self.parts[p].height_m
            for p in self._future_parts(target)
            if p != part_id and self._layer(self.parts[p], target) < layer
        )

    def busy_stations(self) -> set[str]:
        """Stations some assigned or running task picks from or places at (one arm at a time there)."""
        return {s for t in self.open_tasks() if t.state in TAKEN_STATES for s in t.stations}
