"""How often, in ticks, a sim server does each of its periodic things: fixed by the scene's control rate."""

from __future__ import annotations

from dataclasses import dataclass

from coordinator.cadence import decision_period_ticks
from robots.skills.pick_place import DEFAULT_DECISION_HZ
from scenes.schema import Scene

MAX_CONTROLLER_PERIOD_S = 1.0  # the longest a controller may ask to wait for its next state
VIEW_RATE_HZ = 25.0  # sim-time rate of the monitors' `LineView`


@dataclass(frozen=True)
class SimCadence:
    """Periods in ticks of the scene's control rate (`control_hz`)."""

    control_hz: float
    decision_ticks: int  # a controller's states, until it asks for another rate; the line's events likewise
    max_period_ticks: int  # the longest a controller may ask to wait for its next state
    view_every_ticks: int  # the monitors' `LineView`
    coord_period_ticks: int  # the coordinator's frames

    @classmethod
    def of(cls, scene: Scene) -> SimCadence:
        hz = scene.control_hz
        return cls(
            control_hz=hz,
            decision_ticks=max(1, round(hz / DEFAULT_DECISION_HZ)),
            max_period_ticks=max(1, round(hz * MAX_CONTROLLER_PERIOD_S)),
            view_every_ticks=max(1, round(hz / VIEW_RATE_HZ)),
            coord_period_ticks=decision_period_ticks(scene),
        )
