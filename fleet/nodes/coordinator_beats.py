"""The coordinator's view of the controllers' lives: heartbeats, which incarnation of each controller to believe
(the launcher's roster on a line it started), arms lost and rejoined, and orders an arm took that this coordinator
never gave. One concern of `CoordinatorNode`, kept apart."""

from __future__ import annotations

import sys
import time

import zenoh

from fleet.bus.keys import Keys
from fleet.bus.message_checks import heartbeat_problem
from fleet.bus.messages import ArmStatus, Roster


class CoordinatorBeats:
    """Heartbeats and incarnations, mixed into `CoordinatorNode`."""

    def _on_heartbeat_arrival(self, sample: zenoh.Sample) -> None:
        """Only stamps the arrival time: a coordinator busy planning must not mistake queued heartbeats for silence."""
        try:
            self._heard_at[Keys.arm_of(str(sample.key_expr))] = time.monotonic()
        except ValueError:
            pass

    def _on_roster(self, key: str, roster: Roster) -> None:
        problem = self.incarnations.roster_problem(roster)
        if problem:
            self.drops.drop(key, problem)
        else:
            self.incarnations.hear_roster(roster)

    def status_problem(self, key: str, s: ArmStatus) -> str:
        """Why a decoded heartbeat cannot be its controller's ("" if it can): numbers no controller sends, another
        arm's, a replaced controller's, or the lost controller's own while the sim still does not hear it (a
        controller that comes back answers the sim first; its heartbeats alone are no rejoin)."""
        if s.arm not in self.last_tick:
            return f"a heartbeat of no arm of this line ({s.arm!r})"
        if Keys.arm_of(key) != s.arm:
            return f"a heartbeat of {s.arm} on another arm's key"
        if problem := heartbeat_problem(s):
            return problem
        if s.incarnation in self._replaced.get(s.arm, ()):
            return f"a late heartbeat of a controller of {s.arm} already replaced"
        lost_one = self.controller_incarnation.get(s.arm) if s.arm in self.dispatcher.lost else None
        if s.incarnation == lost_one and s.arm in getattr(self, "sim_lost", ()):
            return (
                f"a heartbeat of {s.arm}'s lost controller (incarnation {s.incarnation}), which the sim does not hear"
            )
        return self.incarnations.problem(s.arm, s.incarnation) if self.incarnations.from_roster else ""

    def _on_status(self, key: str, s: ArmStatus) -> None:
        known = self.controller_incarnation.setdefault(s.arm, s.incarnation)
        if known != s.incarnation:  # the first beat of a new controller: heard now (its arrival stamp may still
            self._heard_at[s.arm] = max(self._heard_at.get(s.arm, 0.0), time.monotonic())  # be the old one's)
        previous = self.heartbeat_at.get(s.arm)
        self.heartbeat_at[s.arm] = self._heard_at.get(s.arm, time.monotonic())
        if known != s.incarnation:  # restarted faster than the heartbeat timeout: still a loss
            self._replaced.setdefault(s.arm, set()).add(known)
            self.controller_incarnation[s.arm] = s.incarnation
            if s.arm not in self.dispatcher.lost:
                # silent since the old controller's last beat, where this coordinator heard one since it started
                # or was restored (wall-clock stamps start afresh then: no figure rather than the clock's age)
                silent = self.heartbeat_at[s.arm] - previous if previous is not None else 0.0
                self._arm_lost(s.arm, "its controller restarted", silent)
        if s.arm in self.dispatcher.lost:  # a respawned controller rejoined; the sim says so when it has heard it,
            self._rejoining.add(s.arm)  # and its `lost` flag until then is not a second loss
        self.dispatcher.arm_rejoined(s.arm)
        self._check_orders_taken(key, s)

    def _check_orders_taken(self, key: str, s: ArmStatus) -> None:
        """An arm that took an order numbered past this coordinator's count took one it never gave (a lie on the
        assign key): counted, and this coordinator's count moves past it so its own next order is not refused as
        old."""
        if s.assign_seq > self.assign_seq[s.arm]:
            self.drops.drop(key, f"{s.arm} took order {s.assign_seq}, which this coordinator did not give")
            self.assign_seq[s.arm] = s.assign_seq

    def _check_heartbeats(self) -> None:
        """An arm silent for `heartbeat_timeout_s` while the sim is still heard is lost. When the sim is silent too
        (its loop ended and the line is being stopped), the silence is the line's, not the arm's."""
        now = time.monotonic()
        if now - self._frame_at > self.heartbeat_timeout_s:
            return
        for arm in self.heartbeat_at:
            at = self._heard_at.get(arm, self.heartbeat_at[arm])
            if arm not in self.dispatcher.lost and now - at > self.heartbeat_timeout_s:
                self._arm_lost(arm, f"no heartbeat for {self.heartbeat_timeout_s} s", silent_for_s=now - at)

    def _arm_lost(self, arm: str, why: str, silent_for_s: float) -> None:
        self._tell_lost(arm, why, self.dispatcher.arm_lost(arm, why, silent_for_s))

    @staticmethod
    def _tell_lost(arm: str, why: str, returned: list[int]) -> None:
        print(
            f"coordinator: arm {arm} lost ({why}); {len(returned)} task(s) back in the pool",
            file=sys.stderr,
            flush=True,
        )
