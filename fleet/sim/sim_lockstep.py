"""The sim server's lockstep: the answers due at a tick awaited (with the goals they name) and applied, a silent
controller lost, the run's end settled."""

from __future__ import annotations

import time

from fleet.bus.lockstep import ArmLink, unanswered
from fleet.bus.messages import (
    ControllerStep,
)


class SimLockstep:
    """Lockstep at the sim: one concern of `SimServer`, kept apart (the bus-level link and barrier are
    `fleet.bus.lockstep`)."""

    def _apply_answers(self, link: ArmLink) -> None:
        """Lockstep: the answers due now take effect, each with the goals it names; goals no answer names
        (a user's own client, a lost controller) go with them."""
        batches, unnamed = link.take_due(self.world.tick)
        for goals, answer in batches:
            for goal in goals:
                self.inputs.submit(link, goal)
            self.apply_answer(link, answer)
        for goal in unnamed:
            self.inputs.submit(link, goal)

    def apply_answer(self, link: ArmLink, msg: ControllerStep) -> None:
        """The controller's answer takes effect (its goals are with the tracker): what it does, when it wants its
        next state, the watchdog's next deadline."""
        latest = msg.tick >= link.book.newest_delivered  # no later state went out: the schedule is still its to set
        link.last_step = msg
        period = min(max(msg.next_tick - msg.tick, 1), self.max_period_ticks)
        link.period_ticks = period
        if latest:
            link.next_tick = msg.tick + period
        hz = self.world.scene_model.control_hz
        self.tracked.trackers[link.name].watch(
            max(link.next_tick, self.world.tick) / hz + self.watchdog_s + self._round_trip_s(link)
        )
        link.watchdog_held = False
        if link.lost:
            link.lost = False
            self.stats.rejoined.append(link.name)

    def _round_trip_s(self, link: ArmLink) -> float:
        """The longest a state and its answer are expected to travel on this link (latency and 3 sigma of jitter)."""
        f = link.book.link.faults
        return 2 * (f.latency_ms + 3 * f.jitter_ms) / 1e3

    def _wait_for_answers(self, links: list[ArmLink], coord: bool) -> None:
        """Until every live controller of `links` has answered each state delivered to it (with the goals it names),
        and the coordinator each frame (`coord`), or the timeout passed; then the answers due now take effect."""
        outcome = self.barrier.wait(
            links,
            self.coord_book if coord and not self.stats.coordinator_lost else None,
            first=not self.started,
            take_inputs=self.inputs.take,
            pause=self.bus.inbox.wait,
            lose=self._lose,
            republish=self._republish,
            should_stop=self.stop.should_stop if self.stop is not None else lambda: False,
        )
        if outcome == "stopped":
            return
        self.stats.coordinator_lost = self.stats.coordinator_lost or outcome == "coordinator_lost"
        self._apply_due(links, coord)

    def _republish(self, link: ArmLink | None, payload: bytes) -> None:
        """A state (or, `link` None, a frame) still unanswered, sent again."""
        if link is None:
            self.bus.put(self.bus.frame_pub, "frame", payload)
        else:
            self.bus.put(self.bus.state_pubs[link.name], "state", payload)

    def _apply_due(self, links: list[ArmLink], coord: bool) -> None:
        """The answers (controllers', coordinator's) due at this tick take effect."""
        for link in links:
            self._apply_answers(link)
        if coord:
            for flight in self.coord_book.due_answers(self.world.tick):
                self.apply_coord(flight.answer)
        if not self.started and all(link.last_step is not None or link.lost for link in self.links.values()):
            self.started = True  # realtime: from here on answers apply when they arrive

    def _lose(self, link: ArmLink) -> None:
        """A controller silent past the lockstep timeout: its arm holds, its goals are aborted."""
        link.lost = True
        link.book.clear()
        self.stats.lost.append(link.name)
        self.outputs.results(
            link.name, self.tracked.abort(link.name, "the controller was lost (silent past the lockstep timeout)")
        )

    def settle(self) -> None:
        """Lockstep, after the last tick: wait (at most the lockstep timeout) for the answers to the states and frames
        already delivered, and the goals they name, so that the run ends on the bus the same way every time (a
        recording of it too). They take no effect: the run is over."""
        if not (self.deferred or self.deferred_coord):
            return
        deadline = time.monotonic() + self.lockstep_timeout_s
        while time.monotonic() < deadline:
            self.inputs.take()
            links = list(self.links.values()) if self.deferred else []
            coord = self.coord_book if self.deferred_coord and not self.stats.coordinator_lost else None
            if unanswered(links, coord) == ([], False):
                return
            self.bus.inbox.wait(0.01)
