"""Messages in flight on one of the sim's links: when each state (or frame) reaches its process, which answer is
awaited, and when each answer takes effect.

Lockstep: a state sampled at tick T reaches the controller at T + d_down (ticks, from the link's faults), its
answer takes effect `period` ticks after that plus d_up, and the answer's fate (lost or not) is drawn when
the state is sent, so a run repeats exactly. A process answers the newest state it holds, so of the states
due at once only the newest is delivered, and one that would arrive after a newer one is dropped (overtaken):
the sim never waits for an answer that will not come. Without faults a state arrives when sampled and its
answer takes effect one period later, which is the plain lockstep protocol. Realtime delivers by the wall
clock and leaves the answers' delays to the caller (`fleet.bus.faults.DelayLine`).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any, Generic, TypeVar

import msgspec

from fleet.bus.faults import FaultyLink, ticks_for
from robots.saved_state import SavedState

M = TypeVar("M")  # what a link carries out (a state, a frame)
A = TypeVar("A")  # the answer to it


@dataclass
class Flight:
    """One state (or frame) sent on a link, and its answer once in."""

    tick: int  # sampled at
    message: Any
    deliver_tick: int  # lockstep: the tick it reaches the process
    deliver_at_s: float  # realtime: the wall time it reaches the process
    apply_tick: int  # lockstep: the tick its answer takes effect
    up_lost: bool  # lockstep: its answer is lost on the way back
    delivered: bool = False
    payload: bytes = b""  # as delivered (encoded then: a delayed state carries the tick it arrived)
    answer: Any = None
    delivered_wall_s: float = 0.0


class FlightState(SavedState, Generic[M, A], frozen=True):
    """A `Flight` saved, with its message and answer of the link's own types."""

    tick: int
    message: M
    deliver_tick: int
    deliver_at_s: float
    apply_tick: int
    up_lost: bool
    delivered: bool
    payload: bytes
    answer: A | None
    delivered_wall_s: float


class BookState(SavedState, Generic[M, A], frozen=True):
    """What a `FlightBook` saves: its flights, oldest first, and the newest delivered and applied."""

    flights: list[FlightState[M, A]]
    newest_delivered: int
    newest_applied: int


def flight_state(f: Flight) -> FlightState:
    """A flight as saved: every field of `Flight` (one it adds that the saved form lacks fails here, not silently)."""
    return FlightState(**{field.name: getattr(f, field.name) for field in fields(Flight)})


def flight_of(s: FlightState) -> Flight:
    return Flight(**msgspec.structs.asdict(s))


class FlightBook:
    """The states one link carries and has not settled; `send`, `deliver`, `answer`, `due_answers`."""

    def __init__(self, link: FaultyLink, hz: float) -> None:
        self.link, self.hz = link, hz
        self.flights: dict[int, Flight] = {}  # by sample tick, oldest first
        self.newest_delivered = -1
        self.newest_applied = -1

    def send(self, tick: int, message: Any, period_ticks: int, now_wall_s: float, lockstep: bool) -> Flight | None:
        """A state sampled at `tick` goes out: its fate drawn (None: lost on the way)."""
        down = self.link.passage("down")
        if down.lost:
            return None
        up = self.link.passage("up") if lockstep else None
        d = ticks_for(down.delay_s, self.hz)
        up_ticks = ticks_for(up.delay_s, self.hz) if up is not None else 0
        flight = Flight(
            tick,
            message,
            tick + d,
            now_wall_s + down.delay_s,
            tick + d + period_ticks + up_ticks,
            up is not None and up.lost,
        )
        self.flights[tick] = flight
        return flight

    def deliver(self, tick: int, now_wall_s: float, lockstep: bool) -> Flight | None:
        """The flight that reaches its process now: the newest of those due (older ones are overtaken)."""
        due = [
            f
            for f in self.flights.values()
            if not f.delivered and (f.deliver_tick <= tick if lockstep else f.deliver_at_s <= now_wall_s)
        ]
        if not due:
            return None
        newest = max(due, key=lambda f: f.tick)
        for f in due:
            if f is not newest or f.tick < self.newest_delivered:
                self.link.note("down", "overtaken")
                del self.flights[f.tick]
        if newest.tick < self.newest_delivered:
            return None
        newest.delivered, newest.delivered_wall_s = True, now_wall_s
        self.newest_delivered = newest.tick
        return newest

    def awaiting(self) -> Flight | None:
        """A delivered flight still unanswered (lockstep has at most one: each is answered before the next arrives)."""
        return next((f for f in self.flights.values() if f.delivered and f.answer is None), None)

    def answer(self, tick: int, answer: Any) -> Flight | None:
        """Record the answer to the state of `tick`; None when no delivered state of that tick awaits one."""
        flight = self.flights.get(tick)
        if flight is None or not flight.delivered or flight.answer is not None:
            return None
        flight.answer = answer
        if flight.up_lost:
            del self.flights[tick]  # it never reaches the sim: what it carried is discarded by the caller
        return flight

    def due_answers(self, tick: int) -> list[Flight]:
        """Lockstep: the answered flights whose answers take effect at `tick`, oldest first; flights due with no
        answer (their process is lost) and answers older than one already applied (stale) are dropped."""
        out = []
        for f in [f for f in self.flights.values() if f.apply_tick <= tick]:
            del self.flights[f.tick]
            if f.answer is not None:
                out.append(f)
        return self._in_order(out)

    def applied(self, flight: Flight) -> bool:
        """Realtime: an answer is in; True when it is to be applied (not older than one applied already). Older
        flights are settled with it (their answers would be stale)."""
        for t in [t for t in self.flights if t <= flight.tick]:
            del self.flights[t]
        return bool(self._in_order([flight]))

    def _in_order(self, flights: list[Flight]) -> list[Flight]:
        out = []
        for f in flights:
            if f.tick < self.newest_applied:
                self.link.note("up", "stale")
                continue
            self.newest_applied = f.tick
            out.append(f)
        return out

    def arrives(self, tick: int) -> bool:
        """Lockstep: a state sent earlier reaches its process at `tick`."""
        return any(not f.delivered and f.deliver_tick <= tick for f in self.flights.values())

    def applies(self, tick: int) -> bool:
        """Lockstep: an answer takes effect at `tick` (or is overdue)."""
        return any(f.apply_tick <= tick for f in self.flights.values())

    def prune(self, tick: int, keep_ticks: int) -> None:
        """Realtime: forget flights older than `keep_ticks` (their answers will not be used)."""
        for t in [t for t in self.flights if t < tick - keep_ticks]:
            del self.flights[t]

    def clear(self) -> None:
        self.flights.clear()

    def state(self) -> BookState:
        """What this book saves (its link's faults save themselves)."""
        return BookState(
            flights=[flight_state(f) for f in self.flights.values()],
            newest_delivered=self.newest_delivered,
            newest_applied=self.newest_applied,
        )

    def restore(self, state: BookState) -> None:
        self.flights = {f.tick: flight_of(f) for f in state.flights}
        self.newest_delivered, self.newest_applied = state.newest_delivered, state.newest_applied
