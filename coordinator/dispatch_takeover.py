"""A dispatcher taking over a running line: the ledger rebuilt from the event log, each arm's task adopted from its
heartbeat."""

from __future__ import annotations

import math

from coordinator.dispatch_book import ArmBook, DispatchClock
from coordinator.ledger import Ledger
from scenes.schema import Scene

# after a take-over, no grant until the arms settle or this long (sim s): longer than any granted move
SETTLE_CAP_S = 10.0
STATION_MATCH_M = 0.01  # a place position this close (x, y) to a station's is that station


class TakeOver:
    """Taking over a running line: the dispatcher's `arms` held until they settle, their tasks adopted into its
    `ledger`; it keeps what was adopted (the summary's `tasks_adopted`)."""

    def __init__(self, arms: ArmBook, clock: DispatchClock, ledger: Ledger, scene: Scene) -> None:
        self.arms, self.clock, self.ledger, self.scene = arms, clock, ledger, scene
        self.adopted: list[dict] = []

    def take_over(self, time_s: float) -> None:
        """This dispatcher replaces one that crashed (events replayed with `on_event`): the grants it gave are
        unknown, so none is given until every arm was seen holding still for a grant or idle (an arm may still
        be moving under an old grant), or `SETTLE_CAP_S` passed."""
        self.clock.sim_time_s = max(self.clock.sim_time_s, time_s)
        self.arms.unsettled = set(self.arms.names) - set(self.arms.lost)
        self.arms.settle_by_s = time_s + SETTLE_CAP_S

    def adopt(self, arm: str, task_id: int, part_id: int, place_xyz: tuple[float, ...], time_s: float) -> str:
        """The task `arm` says it works on (its controller's heartbeat) joins the ledger as that arm's, if the
        ledger does not know it: a take-over, or an order of the crashed dispatcher that it never announced.
        Returns why not ("" when adopted)."""
        if task_id in self.ledger.tasks:
            return "known"
        station = self.station_at(place_xyz)
        why = (
            f"no station at {tuple(round(v, 3) for v in place_xyz)}"
            if station is None
            else self.ledger.adopt(task_id, part_id, station, arm, time_s)
        )
        if not why:
            self.arms.last_stations[arm], self.arms.last_task[arm] = self.ledger.tasks[task_id].stations, task_id
        self.adopted.append(
            {
                "arm": arm,
                "task_id": task_id,
                "part_id": part_id,
                "station": station,
                "sim_time_s": round(time_s, 3),
                "adopted": not why,
                "reason": why,
            }
        )
        return why

    def station_at(self, place_xyz: tuple[float, ...]) -> str | None:
        """The station whose place position (x, y) is `place_xyz`'s, if one is."""
        if len(place_xyz) != 3:
            return None
        for station in self.scene.stations:
            if math.dist(station.pose.xyz[:2], place_xyz[:2]) < STATION_MATCH_M:
                return station.name
        return None
