"""The coordinator's view of the controllers' lives: heartbeats, which incarnation of each controller to believe
(the launcher's roster on a line it started), arms lost and rejoined, and orders an arm took that the coordinator
never gave."""

from __future__ import annotations

import sys
import time

import zenoh

from coordinator.dispatcher import Dispatcher
from fleet.bus.codec import DropCounter
from fleet.bus.keys import Keys
from fleet.bus.message_checks import Incarnations, heartbeat_problem
from fleet.bus.messages import ArmStatus, Roster
from fleet.snapshot.coordinator_state import LivesState

HEARTBEAT_GAP_S = 0.2  # wall seconds without a frame that make the line's silence, not an arm's: a heartbeat period


class ControllerLives:
    """Heartbeats and incarnations of the controllers of `arms`. It is handed the dispatcher (told of arms lost and
    rejoined), the coordinator's drop counter and its order counts by arm (`assign_seq`, moved past an order an arm
    took that was never given). Wall-clock stamps are this process's: `restart_clocks` after a restore.
    `silence_loses` False (lockstep): no arm is lost for a silent heartbeat, only when the sim says it no longer
    hears its controller or a new incarnation beats; a run that repeats has no wall-clock decision in it."""

    def __init__(
        self,
        arms: list[str],
        dispatcher: Dispatcher,
        drops: DropCounter,
        assign_seq: dict[str, int],
        roster: bool,
        silence_loses: bool = True,
    ) -> None:
        self.silence_loses = silence_loses
        self.arms = frozenset(arms)
        self.dispatcher, self.drops, self.assign_seq = dispatcher, drops, assign_seq
        self.incarnations = Incarnations(from_roster=roster)  # which start of each controller to believe
        self.controller_incarnation: dict[str, int] = {}
        self.heartbeat_at: dict[str, float] = {}  # arm -> wall time of its last heartbeat handled
        self.heard_at: dict[str, float] = {}  # arm -> wall time its last heartbeat arrived (set on arrival)
        self.frame_at = time.monotonic()  # when the sim's last frame believed arrived
        self.frame_heard_at = 0.0  # when the last frame arrived (set on arrival; 0: no arrival stamped)
        self.resumed_at = self.frame_at  # when the line last came back from a stall
        self.rejoining: set[str] = set()  # arms whose new controller beat before the sim heard it
        self.sim_lost: set[str] = set()  # arms whose controller the sim says it no longer hears (their latest state)
        self.replaced: dict[str, set[int]] = {}  # arm -> incarnations of its controllers that were replaced

    def state(self) -> LivesState:
        """What these lives save (their wall-clock stamps start afresh on `restore`)."""
        return LivesState(
            incarnations=self.incarnations.state(),
            controller_incarnation=dict(self.controller_incarnation),
            rejoining=set(self.rejoining),
            sim_lost=set(self.sim_lost),
            replaced={arm: set(i) for arm, i in self.replaced.items()},
        )

    def restore(self, state: LivesState) -> None:
        self.incarnations.restore(state.incarnations)
        self.controller_incarnation = dict(state.controller_incarnation)
        self.rejoining, self.sim_lost = set(state.rejoining), set(state.sim_lost)
        self.replaced = {arm: set(i) for arm, i in state.replaced.items()}
        self.restart_clocks()

    def arrived(self, sample: zenoh.Sample) -> None:
        """A heartbeat's arrival, stamped (a subscriber's callback): a coordinator busy planning must not mistake
        queued heartbeats for silence."""
        try:
            self.heard_at[Keys.arm_of(str(sample.key_expr))] = time.monotonic()
        except ValueError:
            pass

    def frame_arrived(self, _sample: zenoh.Sample | None = None) -> None:
        """A frame's arrival, stamped (a subscriber's callback): the line's life and the arms' heartbeats are judged
        on one clock, when each arrived, however late a busy coordinator reads them."""
        self.frame_heard_at = time.monotonic()

    def restart_clocks(self) -> None:
        """Wall-clock stamps start afresh (after a restore): a heartbeat heard before is no silence now, and no
        controller is judged before it beats again."""
        self.frame_at = self.resumed_at = time.monotonic()
        self.heartbeat_at, self.heard_at = {}, {}

    def frame_read(self) -> None:
        """A frame of the sim was read and believed: the line was alive when it arrived (its arrival stamp, or now
        where none was stamped), so an arm silent since well before is silent of its own. A frame after a gap is
        the line coming back from a stall (a lockstep line waits for its slowest node, and any process may be held
        off the CPU): the arms' heartbeats, held up with it, are judged from then on."""
        at = max(self.frame_heard_at, self.frame_at) if self.frame_heard_at else time.monotonic()
        if at - self.frame_at > HEARTBEAT_GAP_S:
            self.resumed_at = at
        self.frame_at = at

    def on_roster(self, key: str, roster: Roster) -> None:
        problem = self.incarnations.roster_problem(roster)
        if problem:
            self.drops.drop(key, problem)
        else:
            self.incarnations.hear_roster(roster)

    def status_problem(self, key: str, s: ArmStatus) -> str:
        """Why a decoded heartbeat cannot be its controller's ("" if it can): numbers no controller sends, another
        arm's, a replaced controller's, or the lost controller's own while the sim still does not hear it (a
        controller that comes back answers the sim first; its heartbeats alone are no rejoin)."""
        if s.arm not in self.arms:
            return f"a heartbeat of no arm of this line ({s.arm!r})"
        if Keys.arm_of(key) != s.arm:
            return f"a heartbeat of {s.arm} on another arm's key"
        if problem := heartbeat_problem(s):
            return problem
        if s.incarnation in self.replaced.get(s.arm, ()):
            return f"a late heartbeat of a controller of {s.arm} already replaced"
        lost_one = self.controller_incarnation.get(s.arm) if s.arm in self.dispatcher.lost else None
        if s.incarnation == lost_one and s.arm in self.sim_lost:
            return (
                f"a heartbeat of {s.arm}'s lost controller (incarnation {s.incarnation}), which the sim does not hear"
            )
        return self.incarnations.problem(s.arm, s.incarnation) if self.incarnations.from_roster else ""

    def on_status(self, key: str, s: ArmStatus) -> None:
        """A heartbeat believed: its controller alive now (a new one, if a new incarnation: the old one was lost)."""
        known = self.controller_incarnation.setdefault(s.arm, s.incarnation)
        if known != s.incarnation:  # the first beat of a new controller: heard now (its arrival stamp may still
            self.heard_at[s.arm] = max(self.heard_at.get(s.arm, 0.0), time.monotonic())  # be the old one's)
        previous = self.heartbeat_at.get(s.arm)
        self.heartbeat_at[s.arm] = self.heard_at.get(s.arm, time.monotonic())
        if known != s.incarnation:  # restarted faster than the heartbeat timeout: still a loss
            self.replaced.setdefault(s.arm, set()).add(known)
            self.controller_incarnation[s.arm] = s.incarnation
            if s.arm not in self.dispatcher.lost:
                # silent since the old controller's last beat, where this coordinator heard one since it started
                # or was restored (wall-clock stamps start afresh then: no figure rather than the clock's age)
                silent = self.heartbeat_at[s.arm] - previous if previous is not None else 0.0
                self.arm_lost(s.arm, "its controller restarted", silent)
        if s.arm in self.dispatcher.lost:  # a respawned controller rejoined; the sim says so when it has heard it,
            self.rejoining.add(s.arm)  # and its `lost` flag until then is not a second loss
        self.dispatcher.arm_rejoined(s.arm)
        self._check_orders_taken(key, s)

    def on_sim_state(self, arm: str, lost: bool) -> bool:
        """The sim's state of `arm` says whether it hears its controller; whether that counts as the arm lost (not
        while a new controller that already beat is rejoining)."""
        if lost:
            self.sim_lost.add(arm)
        else:
            self.rejoining.discard(arm)
            self.sim_lost.discard(arm)
        return lost and arm not in self.rejoining

    def silent_for_s(self, arm: str) -> float:
        """Wall seconds since `arm`'s last heartbeat arrived."""
        return time.monotonic() - self.heard_at.get(arm, 0.0)

    def _check_orders_taken(self, key: str, s: ArmStatus) -> None:
        """An arm that took an order numbered past the coordinator's count took one it never gave (a lie on the
        assign key): counted, and the count moves past it so the coordinator's own next order is not refused as
        old."""
        if s.assign_seq > self.assign_seq[s.arm]:
            self.drops.drop(key, f"{s.arm} took order {s.assign_seq}, which this coordinator did not give")
            self.assign_seq[s.arm] = s.assign_seq

    def check(self, timeout_s: float) -> None:
        """An arm is lost when the sim was heard (a frame arrived) more than `timeout_s` (wall) after the arm's last
        heartbeat arrived: silent that long while the line ran. A line that goes silent with its arms (its run
        ended and its nodes are being stopped, or it stalled) loses none, however long the arms' last beats came
        before its last frame within that time; and for `timeout_s` after the line comes back from a stall, the
        arms' heartbeats, held up with it, are still to come. Never on a lockstep line (`silence_loses`)."""
        if not self.silence_loses or time.monotonic() - self.resumed_at <= timeout_s:
            return
        for arm in self.heartbeat_at:
            at = self.heard_at.get(arm, self.heartbeat_at[arm])
            if arm not in self.dispatcher.lost and self.frame_at - at > timeout_s:
                self.arm_lost(arm, f"no heartbeat for {timeout_s} s", silent_for_s=self.frame_at - at)

    def arm_lost(self, arm: str, why: str, silent_for_s: float) -> None:
        tell_lost(arm, why, self.dispatcher.arm_lost(arm, why, silent_for_s))


def tell_lost(arm: str, why: str, returned: list[int]) -> None:
    """Say on stderr that `arm` was lost and how many of its tasks went back to the pool."""
    print(f"coordinator: arm {arm} lost ({why}); {len(returned)} task(s) back in the pool", file=sys.stderr, flush=True)
