"""The ledger's stations: stacks and assemblies at fixtures, which part may go in next, which are busy, how high a
place is; and which stations a part's hop may end at."""

from __future__ import annotations

from coordinator.ledger_records import LedgerRecords
from coordinator.tasks import OPEN_STATES, TAKEN_STATES, PartFate, PartRecord, Task, TaskState
from scenes.schema import Scene


def alternatives(scene: Scene, part: PartRecord) -> tuple[str, ...]:
    """Stations as good as the part's next one: on its last hop, a sorted part's bins of its colour."""
    if part.hop != len(part.route) - 1:
        return ()
    return tuple(scene.stations_for_colour(part.feeder, part.type_index))


def other_stations(scene: Scene, part: PartRecord) -> tuple[str, ...]:
    """The part's alternatives besides its next station (what a task to the next station carries)."""
    return tuple(s for s in alternatives(scene, part) if s != part.next_station)


class StationTurns:
    """Whose turn it is at each station, from `records`: with `pipeline`, a fixture's next part may be given to an
    arm before the fixture is ready for it (the arm holds it at the edge until `may_enter`)."""

    def __init__(self, records: LedgerRecords, scene: Scene, pipeline: bool) -> None:
        self.records = records
        self.scene = scene
        self.pipeline = pipeline
        self.gated = {s.name for s in scene.stations if s.kind == "fixture"}  # one part or assembly at a time

    def pipelined(self, station: str) -> bool:
        """Whether parts for `station` may be given out before it is ready for them (a fixture, with pipelining)."""
        return self.pipeline and station in self.gated

    def ready(self, part: PartRecord, target: str, besides: Task | None = None) -> bool:
        """Precedence: an assembly layer needs the layers below it; a stack's bottom leaves only when whole.
        With pipelining, layers and parts on their way count as there (their arms wait at `may_enter`)."""
        parts, here = self.records.parts, self.records.stacks.get(part.location)
        if here is not None and part.part_id in here:
            whole = len(self.scene.station(part.location).assembles)
            if here[0] != part.part_id or (not self.pipeline and len(here) < whole):
                return False
            if self.pipeline:  # every layer placed, or an arm bringing it (a second part of one layer is not the next)
                have = {self.layer(parts[p], part.location) for p in here}
                have |= {
                    self.layer(parts[t.part_id], part.location)
                    for t in self.records.inbound(part.location, TAKEN_STATES)
                }
                if not set(range(whole)) <= have:
                    return False
        stack = self.records.stacks.get(target)
        assembles = self.scene.station(target).assembles
        if self.pipelined(target):  # a layer below counts once an arm brings it: a task for it that waits for an
            # arm must not wait behind this one, given to the same arm (which would hold this at the edge)
            layer, coming = self.layer(part, target), self.future_layers(target, TAKEN_STATES, besides)
            return layer not in self.future_layers(target, OPEN_STATES, besides) and all(
                below in coming for below in range(layer)
            )
        if stack is not None and part.feeder in assembles:
            if len(stack) != assembles.index(part.feeder):
                return False
            if any(t.target == target for t in self.records.open_tasks()):
                return False  # one layer on its way at a time
        return True

    def layer(self, part: PartRecord, station: str) -> int:
        """Where `part` goes in `station`'s stack (0, the bottom, at a station that does not assemble)."""
        assembles = self.scene.station(station).assembles
        return assembles.index(part.feeder) if part.feeder in assembles else 0

    def occupants(self, station: str) -> list[int]:
        """The parts resting at `station`: its stack, if it assembles; else every part there."""
        if station in self.records.stacks:
            return self.records.stacks[station]
        return [p.part_id for p in self.records.parts.values() if p.location == station and p.fate == PartFate.ON_LINE]

    def future_parts(
        self, station: str, states: tuple[TaskState, ...] = OPEN_STATES, besides: Task | None = None
    ) -> list[int]:
        """The parts `station` will hold once the parts on their way (tasks in `states`, but `besides`) are there
        and the ones an arm was sent to take away are gone."""
        present = [] if self.leaving(station) else list(self.occupants(station))
        return present + [t.part_id for t in self.records.inbound(station, states) if t is not besides]

    def future_layers(
        self, station: str, states: tuple[TaskState, ...] = OPEN_STATES, besides: Task | None = None
    ) -> list[int]:
        """The layers of `future_parts`."""
        return [self.layer(self.records.parts[p], station) for p in self.future_parts(station, states, besides)]

    def withdraw_if_stale(self, task: Task, part: PartRecord) -> None:
        """A pending task into a pipelined fixture that its part is no longer ready for (the layer below it was
        lost, or failed, before an arm took it) is withdrawn: an arm given it would hold its part at the edge for
        a layer that may never come, or that only it could bring."""
        if task.state == TaskState.PENDING and self.pipelined(task.target):
            if task.target == part.next_station and not self.ready(part, task.target, besides=task):
                self.records.drop(task)

    def leaving(self, station: str) -> bool:
        """What rests at `station` is whole (an assembly with every layer) and an arm was sent to take it away."""
        here, assembles = self.occupants(station), self.scene.station(station).assembles
        whole = len(here) >= len(assembles) if assembles else bool(here)  # a part taken along by a claw may lie on top
        return whole and any(t.source == station and t.state in TAKEN_STATES for t in self.records.open_tasks())

    def may_enter(self, task: Task, station: str) -> bool:
        """May the arm of `task` move into `station` now? Always, unless pipelining holds it: taking an assembly
        away waits until it is whole; bringing a part waits until the layers below it are placed and the parts
        before it (an assembly, a handed-over part) have been lifted off, and no arm is bringing one below it."""
        if not self.pipelined(station):
            return True
        assembles = self.scene.station(station).assembles
        here = self.occupants(station)
        if station == task.source:
            return not assembles or (bool(here) and here[0] == task.part_id and len(here) >= len(assembles))
        layer = self.layer(self.records.parts[task.part_id], station)
        if any(
            t.task_id != task.task_id and self.layer(self.records.parts[t.part_id], station) <= layer
            for t in self.records.inbound(station, TAKEN_STATES)
        ):
            return False
        return len(here) == layer

    def enterable_now(self, part: PartRecord, station: str) -> bool:
        """Whether `part` could be set on `station` now: the layers below it placed, nothing there at its layer and
        no arm bringing a part at or below its layer (`may_enter`, for a task not given out yet)."""
        layer = self.layer(part, station)
        if len(self.occupants(station)) != layer:
            return False
        return not any(
            self.layer(self.records.parts[t.part_id], station) <= layer
            for t in self.records.inbound(station, TAKEN_STATES)
        )

    def place_height_m(self, target: str, part_id: int | None = None) -> float:
        """Where a part's bottom goes at `target`: the station's surface, on top of any stack there (with
        pipelining, on the layers below `part_id`'s, placed or on their way, not on an assembly leaving)."""
        parts, z = self.records.parts, self.scene.station(target).surface_z_m
        if not (self.pipelined(target) and part_id is not None):
            return z + sum(parts[p].height_m for p in self.records.stacks.get(target, []))
        layer = self.layer(parts[part_id], target)
        below = (p for p in self.future_parts(target) if p != part_id and self.layer(parts[p], target) < layer)
        return z + sum(parts[p].height_m for p in below)

    def busy_stations(self) -> set[str]:
        """Stations some assigned or running task picks from or places at (one arm at a time there)."""
        return {s for t in self.records.open_tasks() if t.state in TAKEN_STATES for s in t.stations}
