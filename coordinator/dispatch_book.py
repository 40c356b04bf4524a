"""What the dispatcher knows of its arms and of the line's time between decisions. The dispatcher's components (the
allocator's views, grant answers, outside drivers, take-over) are each handed these objects, not the dispatcher."""

from __future__ import annotations

import math
from dataclasses import dataclass

from coordinator.guard import TimedPath
from robots.phase import Phase


class ArmBook:
    """Each arm as its reports and the dispatcher's own orders leave it: its phase, its motion request, its last task,
    whether it is lost or taken by an outside driver, and the log of those events (the summary's `arm_events`)."""

    def __init__(self, arm_names: list[str]) -> None:
        self.names = list(arm_names)
        self.phase: dict[str, str] = {a: Phase.IDLE for a in self.names}
        self.acts_at_tick = {a: 0 for a in self.names}  # when an order sent now takes effect on each arm
        self.last_stations: dict[str, tuple[str, ...]] = {a: () for a in self.names}
        self.last_task: dict[str, int] = {}  # each arm's latest task (where it is leaving from, once it is closed)
        self.requests: dict[str, TimedPath] = {}  # motion requests waiting for a decision, by arm (the newest wins)
        self.request_seq: dict[str, int] = {a: 0 for a in self.names}
        self.lost: dict[str, float] = {}  # arm -> when it was lost (or taken: out of the allocation either way)
        self.taken: set[str] = set()  # arms an outside client drives (`OutsideDrivers`)
        self.busy_until_s: dict[str, float] = {}  # when each arm's current task should end (the allocator's estimate)
        self.unsettled: set[str] = set()  # after a take-over: arms that may still move under a grant given before it
        self.settle_by_s = -math.inf
        self.losses: list[dict] = []  # lost, rejoined, taken, let go: the summary's `arm_events`


@dataclass
class DispatchClock:
    """The line's sim time as the dispatcher last heard it: the parts' time, the latest line event (the run's end,
    at its report, may be later than its parts) and the last decision's tick."""

    sim_time_s: float = 0.0
    last_event_s: float = 0.0
    last_decision_tick: int = -(10**9)
