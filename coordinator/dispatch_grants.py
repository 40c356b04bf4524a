"""Motion requests answered: each arm's free move checked by the guard against the others' committed paths, a fixture's
turn kept, separations watched."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from coordinator.dispatch_book import ArmBook, DispatchClock
from coordinator.guard import CollisionGuard, NearestPair
from coordinator.ledger import Ledger
from coordinator.orders import GrantOrder
from coordinator.tasks import TAKEN_STATES, Task
from robots.phase import GRASP_PHASES, LOCAL_PHASES, PLACE_PHASES, Phase


class GrantAnswers:
    """Answering the arms' motion requests (`arms.requests`) with the `guard`, in the `ledger`'s turns at fixtures;
    it keeps the grants given, the moves held for a fixture and the cell's closest approach. `decision_s`: a
    decision's period in sim seconds (how long a held move waited)."""

    def __init__(
        self,
        arms: ArmBook,
        clock: DispatchClock,
        ledger: Ledger,
        guard: CollisionGuard,
        control_hz: float,
        decision_s: float,
    ) -> None:
        self.arms, self.clock, self.ledger, self.guard = arms, clock, ledger, guard
        self.control_hz, self.decision_s = control_hz, decision_s
        self.grants_given = 0
        self.held_at_station_s: dict[str, float] = {}  # pipelining: how long each arm's moves waited for a fixture
        self.held_now: dict[str, str] = {}  # arm -> the fixture its waiting move is held for, at the last decision
        self.told_standby: set[int] = set()  # tasks whose held transfer was told to stand by (once a task)
        self.min_separation_m = math.inf
        self.closest_pair: tuple[str, str] | None = None

    def answer_motion_requests(self, now_s: float) -> list[GrantOrder]:
        """Check every waiting request with the guard, arms in scene order (one global order: no cycle of waits).

        A grant starts when the arm next hears from the sim (its controller acts on it then), for the duration
        asked; `deny` (an arm that is not moving is in the way) goes back to the arm; `wait` (an arm with a
        granted move is in the way) stays here until that move is over.
        """
        self.guard.expire(now_s)
        arms = self.arms
        if arms.unsettled and now_s < arms.settle_by_s:
            return []  # taken over: an arm may still move under a grant this dispatcher never saw
        arms.unsettled.clear()
        out = []
        self.held_now = {}
        for arm in [a for a in arms.names if a in arms.requests]:
            station = self.station_ahead(arm)
            if station is not None:  # pipelined: the fixture is not ready for this arm's part yet
                self.held_now[arm] = station
                self.held_at_station_s[arm] = self.held_at_station_s.get(arm, 0.0) + self.decision_s
                task = self.open_task(arm)
                # wait beside it, part in hand
                if arms.phase[arm] == Phase.TRANSFER and task.task_id not in self.told_standby:
                    self.told_standby.add(task.task_id)
                    del arms.requests[arm]
                    out.append(GrantOrder(arm, arms.request_seq[arm], "standby", "", math.inf, None))
                continue
            asked = arms.requests[arm]
            start = max(arms.acts_at_tick[arm], self.clock.last_decision_tick + 1) / self.control_hz
            path = dataclasses.replace(asked, t_start_s=start, t_end_s=start + (asked.t_end_s - asked.t_start_s))
            self.guard.set_state(arm, np.asarray(asked.q_from))
            verdict = self.guard.request(path)
            if verdict.decision == "wait":
                continue
            del arms.requests[arm]
            self.grants_given += verdict.granted
            out.append(
                GrantOrder(
                    arm,
                    arms.request_seq[arm],
                    verdict.decision,
                    verdict.conflict_arm or "",
                    verdict.min_separation_m,
                    start if verdict.granted else None,
                )
            )
        return out

    def open_task(self, arm: str) -> Task | None:
        """The task `arm` was given and has not finished."""
        return next((t for t in self.ledger.open_tasks() if t.arm == arm and t.state in TAKEN_STATES), None)

    def station_ahead(self, arm: str) -> str | None:
        """The fixture `arm`'s waiting move would take it into while it is not ready (None: no such fixture): an
        approach to take from one, a transfer to place on one. Not ready: the ledger holds the part back, or
        another arm works there or is on its way in (`_at_station`)."""
        if not self.ledger.pipeline:
            return None
        task = self.open_task(arm)
        phase = self.arms.phase.get(arm)
        station = (
            task.source
            if task and phase == Phase.APPROACH
            else task.target
            if task and phase == Phase.TRANSFER
            else None
        )
        if station is None or station not in self.ledger.gated:
            return None
        if not self.ledger.may_enter(task, station):
            return station
        return station if any(b != arm and self._at_station(b, station) for b in self.arms.names) else None

    def _at_station(self, arm: str, station: str) -> bool:
        """Is `arm` working at `station` or moving into it under a grant: taking from it (its approach granted,
        the grasp), placing on it (its transfer granted, the place), or still grasping or placing there after its
        task closed. One arm at a fixture at a time, whatever the ledger thinks is there: the guard checks moves,
        but two arms working one spot leave it no safe order."""
        phase = self.arms.phase[arm]
        if arm in self.arms.lost:
            return False
        if station in self.arms.last_stations[arm] and phase in LOCAL_PHASES:
            return True
        task = self.open_task(arm)
        if task is None:
            return False
        granted = arm not in self.arms.requests
        if station == task.source:
            return phase in GRASP_PHASES or (phase == Phase.APPROACH and granted)
        if station == task.target:
            return phase in PLACE_PHASES or (phase == Phase.TRANSFER and granted)
        return False

    def watch_separations(self) -> list[NearestPair]:
        """The cell's closest approach, sampled at the decision rate; each arm's nearest neighbour."""
        pairs = self.guard.nearest_pairs()
        if pairs and pairs[0].distance_m < self.min_separation_m:
            self.min_separation_m, self.closest_pair = pairs[0].distance_m, (pairs[0].a, pairs[0].b)
        return pairs
