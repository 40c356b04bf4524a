"""The sim server's lockstep: the answers due at a tick awaited (with the goals they name) and applied, a silent
controller lost, the run's end settled."""

from __future__ import annotations

import time

from fleet.bus.flights import FlightBook
from fleet.bus.lockstep import ArmLink, Barrier, unanswered
from fleet.common.processes import StopFlag
from fleet.sim.line_controls import LineControls
from fleet.sim.sim_bus import SimBus
from fleet.sim.sim_inputs import SimInputs
from fleet.sim.sim_outputs import SimOutputs
from fleet.sim.sim_stats import SimStats
from fleet.sim.tracking import TrackedArms


class SimLockstep:
    """Waits at the `barrier` for the answers of the arms' `links` and the coordinator's (`coord_book`), takes them in
    through `inputs`, and applies those due; a controller silent past the barrier's timeout is lost (its goals
    aborted on `tracked`, the results out through `outputs`). The bus-level link and barrier are
    `fleet.bus.lockstep`."""

    def __init__(
        self,
        barrier: Barrier,
        bus: SimBus,
        controls: LineControls,
        links: dict[str, ArmLink],
        coord_book: FlightBook,
        inputs: SimInputs,
        outputs: SimOutputs,
        tracked: TrackedArms,
        stats: SimStats,
        stop: StopFlag | None,
    ) -> None:
        self.barrier, self.bus, self.controls = barrier, bus, controls
        self.links, self.coord_book, self.inputs, self.outputs = links, coord_book, inputs, outputs
        self.tracked, self.stats, self.stop = tracked, stats, stop

    def wait_for_answers(self, links: list[ArmLink], coord: bool, tick: int) -> None:
        """Until every live controller of `links` has answered each state delivered to it (with the goals it names),
        and the coordinator each frame (`coord`), or the timeout passed; then the answers due at `tick` take
        effect."""
        outcome = self.barrier.wait(
            links,
            self.coord_book if coord and not self.stats.coordinator_lost else None,
            first=not self.controls.started,
            take_inputs=self.inputs.take,
            pause=self.bus.inbox.wait,
            lose=self._lose,
            republish=self._republish,
            should_stop=self.stop.should_stop if self.stop is not None else lambda: False,
        )
        if outcome == "stopped":
            return
        self.stats.coordinator_lost = self.stats.coordinator_lost or outcome == "coordinator_lost"
        self._apply_due(links, coord, tick)

    def settle(self) -> None:
        """Lockstep, after the last tick: wait (at most the barrier's lockstep timeout) for the answers to the states
        and frames already delivered, and the goals they name, so that the run ends on the bus the same way every
        time (a recording of it too). They take no effect: the run is over."""
        controls = self.controls
        if not (controls.deferred or controls.deferred_coord):
            return
        deadline = time.monotonic() + self.barrier.lockstep_timeout_s
        while time.monotonic() < deadline:
            self.inputs.take()
            links = list(self.links.values()) if controls.deferred else []
            coord = self.coord_book if controls.deferred_coord and not self.stats.coordinator_lost else None
            if unanswered(links, coord) == ([], False):
                return
            self.bus.inbox.wait(0.01)

    def _apply_answers(self, link: ArmLink, tick: int) -> None:
        """The answers due now take effect, each with the goals it names; goals no answer names (a user's own
        client, a lost controller) go with them."""
        batches, unnamed = link.take_due(tick)
        for goals, answer in batches:
            for goal in goals:
                self.inputs.submit(link, goal)
            self.inputs.apply_answer(link, answer)
        for goal in unnamed:
            self.inputs.submit(link, goal)

    def _republish(self, link: ArmLink | None, payload: bytes) -> None:
        """A state (or, `link` None, a frame) still unanswered, sent again."""
        if link is None:
            self.bus.put(self.bus.frame_pub, "frame", payload)
        else:
            self.bus.put(self.bus.state_pubs[link.name], "state", payload)

    def _apply_due(self, links: list[ArmLink], coord: bool, tick: int) -> None:
        """The answers (controllers', coordinator's) due at `tick` take effect."""
        for link in links:
            self._apply_answers(link, tick)
        if coord:
            for flight in self.coord_book.due_answers(tick):
                self.inputs.apply_coord(flight.answer)
        if not self.controls.started and all(link.last_step is not None or link.lost for link in self.links.values()):
            self.controls.started = True  # realtime: from here on answers apply when they arrive

    def _lose(self, link: ArmLink) -> None:
        """A controller silent past the lockstep timeout: its arm holds, its goals are aborted."""
        link.lost = True
        link.book.clear()
        self.stats.lost.append(link.name)
        self.outputs.results(
            link.name, self.tracked.abort(link.name, "the controller was lost (silent past the lockstep timeout)")
        )
