"""Motion requests answered: each arm's free move checked by the guard against the others' committed paths, a fixture's
turn kept, separations watched."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from coordinator.guard import NearestPair
from coordinator.orders import GrantOrder
from coordinator.tasks import TAKEN_STATES, Task
from robots.phase import GRASP_PHASES, LOCAL_PHASES, PLACE_PHASES, Phase


class GrantAnswers:
    """Answering motion requests: one concern of `Dispatcher`, kept apart (it shares the dispatcher's state)."""

    def answer(self, tick: int) -> list[GrantOrder]:
        """Only the motion requests, at `tick`: for a front end whose tasks are chosen elsewhere (the env's allocate
        mode,
        where the policy allocates)."""
        self.last_decision_tick = tick
        return self.answer_motion_requests(tick / self.scene.control_hz)

    def answer_motion_requests(self, now_s: float) -> list[GrantOrder]:
        """Check every waiting request with the guard, arms in scene order (one global order: no cycle of waits).

        A grant starts when the arm next hears from the sim (its controller acts on it then), for the duration
        asked; `deny` (an arm that is not moving is in the way) goes back to the arm; `wait` (an arm with a
        granted move is in the way) stays here until that move is over.
        """
        self.guard.expire(now_s)
        if self.unsettled and now_s < self.settle_by_s:
            return []  # taken over: an arm may still move under a grant this dispatcher never saw
        self.unsettled.clear()
        out = []
        self.held_now = {}
        for arm in [a for a in self.arm_names if a in self.requests]:
            station = self.station_ahead(arm)
            if station is not None:  # pipelined: the fixture is not ready for this arm's part yet
                self.held_now[arm] = station
                self.held_at_station_s[arm] = (
                    self.held_at_station_s.get(arm, 0.0) + self.period_ticks / self.scene.control_hz
                )
                task = self.open_task(arm)
                # wait beside it, part in hand
                if self.phase[arm] == Phase.TRANSFER and task.task_id not in self.told_standby:
                    self.told_standby.add(task.task_id)
                    del self.requests[arm]
                    out.append(GrantOrder(arm, self.request_seq[arm], "standby", "", math.inf, None))
                continue
            asked = self.requests[arm]
            start = max(self.acts_at_tick[arm], self.last_decision_tick + 1) / self.scene.control_hz
            path = dataclasses.replace(asked, t_start_s=start, t_end_s=start + (asked.t_end_s - asked.t_start_s))
            self.guard.set_state(arm, np.asarray(asked.q_from))
            verdict = self.guard.request(path)
            if verdict.decision == "wait":
                continue
            del self.requests[arm]
            self.grants_given += verdict.granted
            out.append(
                GrantOrder(
                    arm,
                    self.request_seq[arm],
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
        phase = self.phase.get(arm)
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
        return station if any(b != arm and self._at_station(b, station) for b in self.arm_names) else None

    def _at_station(self, arm: str, station: str) -> bool:
        """Is `arm` working at `station` or moving into it under a grant: taking from it (its approach granted,
        the grasp), placing on it (its transfer granted, the place), or still grasping or placing there after its
        task closed. One arm at a fixture at a time, whatever the ledger thinks is there: the guard checks moves,
        but two arms working one spot leave it no safe order."""
        phase = self.phase[arm]
        if arm in self.lost:
            return False
        if station in self.last_stations[arm] and phase in LOCAL_PHASES:
            return True
        task = self.open_task(arm)
        if task is None:
            return False
        granted = arm not in self.requests
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
