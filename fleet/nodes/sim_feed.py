"""What the sim tells one arm's controller: its arm's states and the parts on the line, each believed only when it
can be the sim's, and the parts as of each state's own tick."""

from __future__ import annotations

import time
from collections import deque

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.message_checks import TickClock, arm_state_problem, parts_problem, seq_problem
from fleet.bus.messages import ArmState, PartsState
from fleet.bus.session import Inbox
from fleet.nodes.arm_orders import ASSIGNMENT_WAIT_S, ControllerOrders, believable
from fleet.sight.line_sight import carried_to, newest_up_to, seen_parts_problem
from fleet.sight.part_views import parts_from_message
from fleet.snapshot.controller_state import FeedState
from perception.seen_ticks import SeenTicks
from robots.skills.interface import PartObservation

NEWEST_PARTS = 64  # parts messages kept (a state delayed on the bus is matched with the parts of its own time)


class SimFeed:
    """The states of `arm` (with `arm_dof` joints) and the parts, from the controller's inboxes: none may run far
    ahead of the sim's clock (`TickClock` at `control_hz`), and a state may announce only orders `orders` can
    still receive. `parts` are the line's parts as of the last state decided on: the sim's, or with `seen` (the
    line's cameras' frame ticks) perception's, of the newest frame usable at the state's tick."""

    def __init__(
        self,
        arm: str,
        arm_dof: int,
        control_hz: float,
        round_types: frozenset[tuple[str, int]],
        inboxes: dict[str, Inbox],
        decoders: dict[str, Decoder],
        drops: DropCounter,
        orders: ControllerOrders,
        seen: SeenTicks | None = None,
    ) -> None:
        self.arm, self.arm_dof, self.round_types, self.seen = arm, arm_dof, round_types, seen
        self.inboxes, self.decoders, self.drops, self.orders = inboxes, decoders, drops, orders
        self.sim_clock, self.control_hz = TickClock(control_hz), control_hz
        self.parts: dict[int, PartObservation] = {}
        self.parts_tick = -1
        self.parts_seen: deque[PartsState] = deque(maxlen=NEWEST_PARTS)
        self.parts_late = 0  # states planned with older parts (a lockstep run may not repeat)

    def state(self) -> FeedState:
        return FeedState(
            newest_tick=self.sim_clock.newest,
            parts=dict(self.parts),
            parts_tick=self.parts_tick,
            parts_seen=list(self.parts_seen),
            parts_late=self.parts_late,
        )

    def restore(self, state: FeedState) -> None:
        self.sim_clock.newest, self.parts, self.parts_tick = state.newest_tick, dict(state.parts), state.parts_tick
        self.parts_seen = deque(state.parts_seen, maxlen=NEWEST_PARTS)
        self.parts_late = state.parts_late

    def _believed(self, name: str):
        for msg in believable(self.inboxes[name], self.decoders[name], self.drops, self._problem):
            self.sim_clock.believe(msg.tick)
            yield msg

    def _problem(self, msg: ArmState | PartsState) -> str:
        """Why a decoded state or parts message cannot be the sim's ("" if it can)."""
        problem = self.sim_clock.problem(msg.tick)
        if problem:
            return problem
        if isinstance(msg, PartsState):
            return parts_problem(msg) if self.seen is None else seen_parts_problem(msg, self.seen)
        # -1: orders act on arrival
        announced = seq_problem(msg.assign_seq, self.orders.assign_seq) if msg.assign_seq != -1 else ""
        return arm_state_problem(msg, self.arm, self.arm_dof) or announced

    def latest_state(self) -> ArmState | None:
        """The newest believable state of the arm queued (None: none)."""
        latest = None
        for msg in self._believed("state"):
            latest = msg
        return latest

    def take_parts(self) -> None:
        """The parts messages queued, believed and kept."""
        self.parts_seen.extend(self._believed("parts"))

    def parts_in(self, tick: int) -> bool:
        """Whether the parts of `tick` (or later) are in (a tick below 0: none awaited)."""
        return tick < 0 or (bool(self.parts_seen) and self.parts_seen[-1].tick >= tick)

    def parts_for_tick(self, tick: int, now_tick: int | None = None) -> None:
        """The parts as of `tick` (the newest sampled no later). They travel apart from the arm's state, so wait
        (briefly) for that tick's message. With `now_tick` (perception's parts, of an older frame), carried to it."""
        deadline = time.monotonic() + ASSIGNMENT_WAIT_S
        while True:
            self.take_parts()
            newest = newest_up_to(self.parts_seen, tick)
            if newest is not None and (newest.tick != self.parts_tick or now_tick is not None):
                msg = newest if now_tick is None else carried_to(newest, now_tick, self.control_hz)
                self.parts, self.parts_tick = parts_from_message(msg, self.round_types), newest.tick
            if self.parts_in(tick):
                return
            if time.monotonic() > deadline:
                self.parts_late += 1
                return
            self.inboxes["parts"].wait(0.01)

    def skip_parts(self) -> None:
        """No task needs the parts now: the queue is left undecoded but for the newest, kept for when one comes."""
        raw = self.inboxes["parts"].drain()
        if raw:
            self.inboxes["parts"].items.extend(raw[-NEWEST_PARTS:])
