"""What the allocator sees of the arms: which are free, where they stand, when a busy one is free, which stations are
busy."""

from __future__ import annotations

import math

from coordinator.allocation import ArmView, CachedReach
from coordinator.dispatch_book import ArmBook, DispatchClock
from coordinator.guard import CollisionGuard
from coordinator.ledger import Ledger
from coordinator.tasks import TAKEN_STATES, TaskState
from robots.phase import AVAILABLE_PHASES, IDLE_PHASES, Phase

OVERRUN_S = 2.0  # a task this late on its estimate: its arm's end is unknown


class AllocatorViews:
    """The arms as the allocator sees them, from the dispatcher's `arms`, `ledger` and `guard` (where each arm
    stands); `control_hz` turns the last decision's tick into sim time."""

    def __init__(
        self,
        arms: ArmBook,
        clock: DispatchClock,
        ledger: Ledger,
        guard: CollisionGuard,
        reach: dict[str, CachedReach],
        bases: dict[str, tuple[float, float, float]],
        control_hz: float,
    ) -> None:
        self.arms, self.clock, self.ledger, self.guard = arms, clock, ledger, guard
        self.reach, self.bases, self.control_hz = reach, bases, control_hz

    def arm_views(self) -> list[ArmView]:
        arms = self.arms
        open_arms = {t.arm for t in self.ledger.open_tasks() if t.state in TAKEN_STATES}
        return [
            ArmView(
                a,
                self.bases[a],
                a not in arms.lost
                and a not in open_arms
                and arms.phase[a] in AVAILABLE_PHASES
                and not self.leaving_fixture(a),
                self.reach[a],
                tuple(self.guard.state[a].tolist()),
                self.free_in_s(a) if a in open_arms else None,
                a not in arms.lost,
            )
            for a in arms.names
        ]

    def leaving_fixture(self, arm: str) -> bool:
        """Pipelined: an arm on its way home from a fixture takes no task until home. A task taken on the way would
        start its approach from where the way home has got to by its grant, not from where it asked: harmless
        in open space, not next to the arm that works the fixture next. An arm whose task took a part from a
        fixture to a station elsewhere goes home from there, and may (handover: 0.949 -> 0.961 of the run bound
        over 10 seeds of 300 s, when arm_1 no longer went all the way home from the bin before the next part)."""
        return (
            self.ledger.pipeline
            and self.arms.phase[arm] == Phase.HOME
            and bool(self.ledger.gated.intersection(self.leaving_from(arm)))
        )

    def leaving_from(self, arm: str) -> tuple[str, ...]:
        """The stations an arm may be leaving: its last task's target once done (it set the part down there), else
        every station of that task (a task that failed may leave it at either end)."""
        task = self.ledger.tasks.get(self.arms.last_task.get(arm, -1))
        if task is None or task.stations != self.arms.last_stations[arm]:
            return self.arms.last_stations[arm]
        return (task.target,) if task.state == TaskState.DONE else task.stations

    def free_in_s(self, arm: str, now_s: float | None = None) -> float | None:
        """About when a busy arm's task ends (from `now_s`, else the last decision); None once it overran its
        estimate (or is lost): not planned for."""
        now_s = self.clock.last_decision_tick / self.control_hz if now_s is None else now_s
        remaining = self.arms.busy_until_s.get(arm, -math.inf) - now_s
        return None if arm in self.arms.lost or remaining < -OVERRUN_S else max(remaining, 0.0)

    def busy_stations(self, for_arm: str | None = None) -> set[str]:
        """Stations in use: by open tasks, and by arms still moving away from their last task's stations; `for_arm`:
        as that arm sees them (a station it is itself moving away from is free to it: it may go straight back)."""
        busy = self.ledger.busy_stations()
        for arm, stations in self.arms.last_stations.items():
            if arm != for_arm and self.arms.phase[arm] not in IDLE_PHASES and arm not in self.arms.lost:
                busy.update(stations)
        if self.ledger.pipeline:
            busy -= self.ledger.gated  # their order is the ledger's, their moves wait at `station_ahead`
        return busy

    def busy_for_all(self, arms: list[str]) -> set[str]:
        """The stations busy for every one of `arms` (the free ones: what an allocator may be told is busy); a task
        chosen at another station must still be checked against `busy_stations(arm)` for the arm it goes to."""
        return set.intersection(*(self.busy_stations(a) for a in arms)) if arms else self.busy_stations()

    def busy_arms(self) -> int:
        return sum(s not in IDLE_PHASES for s in self.arms.phase.values())
