"""An arm controller's orders from the coordinator: believed only when they can be true, applied at the state that
announces them."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.message_checks import Incarnations, not_finite, seq_problem
from fleet.bus.messages import ArmOrder, Assignment, MotionGrant
from fleet.bus.session import Inbox
from fleet.snapshot.controller_state import OrdersState
from robots.skills.pick_place import PickPlaceSkill

ASSIGNMENT_WAIT_S = 0.5


def believable(inbox: Inbox, decoder: Decoder, drops: DropCounter, problem: Callable[[object], str]) -> Iterator:
    """The messages queued in `inbox` that decode and that `problem` finds nothing wrong with, in arrival order
    (checked one at a time, as the caller takes them); the rest are dropped and counted."""
    for key, payload in inbox.drain():
        msg = decoder.decode(key, payload)
        if msg is None:
            continue
        why = problem(msg)
        if why:
            drops.drop(key, why)
            continue
        yield msg


class ControllerOrders:
    """The coordinator's orders to `arm`, from the inboxes of its order and roster keys (`assign_key` names the
    first in what is dropped): queued as they arrive (`take`), acted on when a state says their time has come
    (`apply`). `pending` is the assignment to start when the skill is free; `grants` the answers to hand it."""

    def __init__(
        self,
        arm: str,
        assign_key: str,
        inboxes: dict[str, Inbox],
        decoders: dict[str, Decoder],
        drops: DropCounter,
        roster: bool,
    ) -> None:
        self.arm, self.assign_key, self.drops = arm, assign_key, drops
        self.inboxes, self.decoders = inboxes, decoders
        self.holders = Incarnations(from_roster=roster)  # which coordinator's orders to believe
        self.assign_seq: int | None = None  # newest order received; None until the first state
        self.received: list[ArmOrder] = []  # orders in, not yet acted on
        self.pending: Assignment | None = None
        self.grants: list[MotionGrant] = []  # answers to motion requests, handed to the skill at the next step
        self.missed = 0  # orders a state announced that never came

    def state(self) -> OrdersState:
        return OrdersState(
            holders=self.holders.state(),
            assign_seq=self.assign_seq,
            received=list(self.received),
            pending=self.pending,
            grants=list(self.grants),
            missed=self.missed,
        )

    def restore(self, state: OrdersState) -> None:
        self.holders.restore(state.holders)
        self.assign_seq, self.received, self.pending = state.assign_seq, list(state.received), state.pending
        self.grants, self.missed = list(state.grants), state.missed

    def _problem(self, msg: ArmOrder) -> str:
        """Why an order cannot be the coordinator's ("" if it can)."""
        if msg.arm != self.arm:
            return f"an order for {msg.arm!r} on {self.arm}'s key"
        problem = self.holders.problem("coordinator", msg.holder) or seq_problem(msg.seq, self.assign_seq)
        if problem:
            return problem
        if isinstance(msg, Assignment):
            values = (msg.surface_z_m, *msg.place_xyz, *msg.surface_velocity)
            if (
                len(msg.place_xyz) != 3
                or len(msg.surface_velocity) != 3
                or not_finite(values)
                or max(map(abs, values)) > 100.0
            ):
                return "an assignment with a place or velocity that is not a finite point"
        elif msg.decision not in ("grant", "deny", "standby") or not_finite((msg.start_time_s, msg.min_separation_m)):
            return "a motion grant that is neither grant, deny nor standby, or with non-finite times"
        return ""

    def take(self) -> None:
        """Queue what arrived; `apply` acts on it when a state says its time has come. Orders come only from the
        coordinator that holds the line (the launcher's roster names it; without one, the newest that spoke), each
        newer than the last."""
        rosters = believable(self.inboxes["roster"], self.decoders["roster"], self.drops, self.holders.roster_problem)
        for roster in rosters:
            self.holders.hear_roster(roster)
        for msg in believable(self.inboxes["assign"], self.decoders["assign"], self.drops, self._problem):
            if self.assign_seq is not None and msg.seq <= self.assign_seq:
                self.drops.drop(self.assign_key, f"order {msg.seq} is not newer than {self.assign_seq}")
                continue
            self.holders.believe("coordinator", msg.holder)
            self.assign_seq = msg.seq
            self.received.append(msg)

    def apply(self, announced_seq: int, skill: PickPlaceSkill) -> None:
        """Act on received orders up to `announced_seq`; on all of them when the sim announces none (-1). A cancel
        stops `skill` where it is."""
        while self.received and (announced_seq < 0 or self.received[0].seq <= announced_seq):
            msg = self.received.pop(0)
            if isinstance(msg, MotionGrant):
                self.grants.append(msg)
            elif msg.task_id is None:  # cancelled: stop where we are
                self.pending = None
                if skill.active:
                    skill.cancel("cancelled by the coordinator")
            else:
                self.pending = msg

    def await_order(self, seq: int) -> None:
        """Lockstep: a state says order `seq` was out before its tick; wait until it is here (or count it missed)."""
        deadline = time.monotonic() + ASSIGNMENT_WAIT_S
        while (self.assign_seq or 0) < seq and time.monotonic() < deadline:
            self.inboxes["assign"].wait(0.01)
            self.take()
        if (self.assign_seq or 0) < seq:
            self.missed += 1
            self.assign_seq = seq
