"""An arm controller's orders from the coordinator: believed only when they can be true, applied at the state that
announces them."""

from __future__ import annotations

import time

from fleet.bus.message_checks import arm_state_problem, not_finite, parts_problem, seq_problem
from fleet.bus.messages import Assignment, MotionGrant, PartsState

ASSIGNMENT_WAIT_S = 0.5


class ControllerOrders:
    """The coordinator's orders to this arm: one concern of `ArmController`, kept apart."""

    def _believable(self, name: str, problem):
        """The messages queued on `name` that decode and that `problem` finds nothing wrong with, in arrival order
        (checked one at a time, as the caller takes them); the rest are dropped and counted."""
        for key, payload in self._inboxes[name].drain():
            msg = self._decoders[name].decode(key, payload)
            if msg is None:
                continue
            why = problem(msg)
            if why:
                self.drops.drop(key, why)
                continue
            yield msg

    def _latest(self, name: str):
        """The newest believable message queued on `name` (states, parts)."""
        latest = None
        for msg in self._believable(name, self._problem):
            self.sim_clock.believe(msg.tick)
            latest = msg
        return latest

    def _problem(self, msg) -> str:
        """Why a decoded state or parts message cannot be the sim's ("" if it can)."""
        problem = self.sim_clock.problem(msg.tick)
        if problem:
            return problem
        if isinstance(msg, PartsState):
            return parts_problem(msg)
        # -1: orders act on arrival
        announced = seq_problem(msg.assign_seq, self.assign_seq) if msg.assign_seq != -1 else ""
        return arm_state_problem(msg, self.arm, self.spec.arm_dof) or announced

    def _order_problem(self, msg) -> str:
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

    def _take_assignments(self) -> None:
        """Queue what arrived; `_apply_assignments` acts on it when a state says its time has come. Orders come
        only from the coordinator that holds the line (the launcher's roster names it; without one, the newest
        that spoke), each newer than the last."""
        for roster in self._believable("roster", self.holders.roster_problem):
            self.holders.hear_roster(roster)
        for msg in self._believable("assign", self._order_problem):
            if self.assign_seq is not None and msg.seq <= self.assign_seq:
                self.drops.drop(self.keys.arm_assign(self.arm), f"order {msg.seq} is not newer than {self.assign_seq}")
                continue
            self.holders.believe("coordinator", msg.holder)
            self.assign_seq = msg.seq
            self.received.append(msg)

    def _apply_assignments(self, announced_seq: int) -> None:
        """Act on received assignments up to `announced_seq`; on all of them when the sim announces none (-1)."""
        while self.received and (announced_seq < 0 or self.received[0].seq <= announced_seq):
            msg = self.received.pop(0)
            if isinstance(msg, MotionGrant):
                self.grants.append(msg)
            elif msg.task_id is None:  # cancelled: stop where we are
                self.pending = None
                if self.skill.active:
                    self.skill.cancel("cancelled by the coordinator")
            else:
                self.pending = msg

    def _await_assignment(self, seq: int) -> None:
        """Lockstep: the state says assignment `seq` was out before this tick; wait until it is here."""
        deadline = time.monotonic() + ASSIGNMENT_WAIT_S
        while (self.assign_seq or 0) < seq and time.monotonic() < deadline:
            self._inboxes["assign"].wait(0.01)
            self._take_assignments()
        if (self.assign_seq or 0) < seq:
            self.missed_assignments += 1
            self.assign_seq = seq
