"""The line's bookkeeping in process: the sim's watcher turns part poses into events, the coordinator's
dispatcher (its ledger) keeps parts and tasks. The same two pieces `fleet run` uses, without the bus between them."""

from __future__ import annotations

from coordinator.dispatcher import Dispatcher
from coordinator.ledger import Ledger
from fleet.sim.line_watch import Event, LineWatcher
from fleet.sim.world import World
from scenes.schema import Scene


class LineBookkeeping:
    """Call `update(world)` after every control tick; `completed` and `missed` count parts so far."""

    def __init__(self, scene: Scene) -> None:
        self.watcher = LineWatcher(scene)
        self.dispatcher = Dispatcher(scene)
        self.log: list[Event] = []  # the episode's events, in order (the env's sight hears them)
        self._counted = 0

    @property
    def ledger(self) -> Ledger:
        return self.dispatcher.ledger

    def update(self, world: World) -> None:
        for e in self.watcher.update(world, world.active_parts()):
            self.log.append(e)
            self.dispatcher.on_event(e.kind, e.part_id, e.detail, e.type_index, world.sim_time_s)

    @property
    def completed(self) -> int:
        return self.ledger.totals()["parts_completed"]

    @property
    def missed(self) -> int:
        totals = self.ledger.totals()
        return totals["parts_missed"] + totals["parts_failed"]

    def net_gain(self) -> int:
        """Parts completed minus parts missed or failed since the last call (the line's reward term)."""
        net = self.completed - self.missed
        gained, self._counted = net - self._counted, net
        return gained
