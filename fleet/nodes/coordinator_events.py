"""The coordinator's event ordering: line events are counted when they arrive and applied at the decision whose tick
reaches them, and a decision waits for every event the sim published before its frame (events and frames travel
on different keys and may arrive in either order; waiting for them is what makes a lockstep run repeat exactly)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from coordinator.dispatcher import Dispatcher
from fleet.bus.codec import DropCounter
from fleet.bus.messages import LineEvent
from fleet.snapshot.coordinator_state import EventGateState


class EventGate:
    """Events held for their decision, and the decision due: `arrived`, `frame`, then `due_now` tells when to decide."""

    def __init__(self, dispatcher: Dispatcher, drops: DropCounter, control_hz: float) -> None:
        self.dispatcher, self.drops, self.control_hz = dispatcher, drops, control_hz
        self.seen = 0  # events received (a frame says how many the sim had published by its tick)
        self.ahead: list[tuple[str, LineEvent]] = []  # received, not yet applied (of a tick past the next decision)
        self.due: tuple[int, int, float] | None = None  # (tick, events published by then, wall deadline)
        self.decided_on_deadline = 0

    def state(self) -> EventGateState:
        return EventGateState(
            seen=self.seen, ahead=list(self.ahead), due=self.due, decided_on_deadline=self.decided_on_deadline
        )

    def restore(self, state: EventGateState) -> None:
        self.seen, self.ahead, self.due = state.seen, list(state.ahead), state.due
        self.decided_on_deadline = state.decided_on_deadline

    def arrived(self, e: LineEvent, key: str) -> None:
        """Counted now, applied at the decision whose tick reaches it: a lockstep sim runs on to the next decision
        while this one is made, and an event of a later tick that arrives first must not change it."""
        self.seen += 1
        self.ahead.append((key, e))

    def apply(self, up_to_tick: int) -> None:
        """Feed the dispatcher the events received of ticks up to `up_to_tick`, in the order they came; one the line
        does not allow (a part arriving twice, one that never arrived) is dropped and counted."""
        later = []
        for key, e in self.ahead:
            if e.tick > up_to_tick:
                later.append((key, e))
                continue
            problem = self.dispatcher.ledger.event_problem(e.kind, e.part_id, e.detail, e.type_index)
            if problem:
                self.drops.drop(key, problem)
            else:
                self.dispatcher.on_event(e.kind, e.part_id, e.detail, e.type_index, e.tick / self.control_hz)
        self.ahead = later

    def frame(self, tick: int, events_published: int, deadline_s: float) -> None:
        """A frame whose tick is a decision's: decide once the events published by then are in (a re-sent frame
        of the same tick changes nothing)."""
        if self.due is None or self.due[0] != tick:
            self.due = (tick, events_published, deadline_s)

    def due_now(self, now_s: float) -> int | None:
        """The tick to decide for now, with its events applied (None: nothing due, or its events not all in and its
        deadline not passed)."""
        if self.due is None:
            return None
        tick, events, deadline = self.due
        complete = self.seen >= events
        if not complete and now_s <= deadline:
            return None
        self.decided_on_deadline += not complete  # decided without every event: a lockstep run may not repeat
        self.due = None
        self.apply(tick)
        return tick


@dataclass
class DecisionTimes:
    """Wall milliseconds each decision took: what a lockstep timeout is measured against."""

    ms: list[float] = field(default_factory=list)
    slowest: tuple[float, int] = (-1.0, -1)  # (ms, tick) of the slowest so far

    def took(self, ms: float, tick: int) -> None:
        self.ms.append(ms)
        if ms > self.slowest[0]:
            self.slowest = (ms, tick)

    def summary(self) -> dict:
        """Median, p99, the slowest and its tick (a lockstep run stops if one takes longer than the sim's timeout)."""
        if not self.ms:
            return {}
        p50, p99 = np.percentile(self.ms, [50, 99])
        return {
            "p50": round(float(p50), 3),
            "p99": round(float(p99), 3),
            "max": round(self.slowest[0], 3),
            "max_at_tick": self.slowest[1],
        }
