"""Realtime: the sim's clock held to the wall clock at the speed factor, and how well it was held. The pacing waits
until each tick is due; the figures say the real-time factor kept over the paced stretches (against the speed asked)
and how late each tick started (its jitter), so a realtime run's clock is measured, not assumed."""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np


def spread_ms(values_ms: list[float] | np.ndarray) -> dict | None:
    """Median, p99 and worst of `values_ms` (ms), None when there are none."""
    values = np.asarray(values_ms, float)
    if values.size == 0:
        return None
    p50, p99 = np.percentile(values, [50, 99])
    return {"p50": round(float(p50), 3), "p99": round(float(p99), 3), "worst": round(float(values.max()), 3)}


@dataclass
class ClockFigures:
    """What the pacing measured: each paced stretch's sim seconds at its speed against the wall seconds it took,
    and how late each tick started against when it was due (ms)."""

    sim_s_at_speed: float = 0.0  # the wall seconds the paced stretches should have taken: sim seconds / speed
    sim_s: float = 0.0
    wall_s: float = 0.0
    late_ms: list[float] = field(default_factory=list)

    def stretch(self, sim_s: float, wall_s: float, speed: float) -> None:
        if sim_s > 0 and wall_s > 0:
            self.sim_s += sim_s
            self.sim_s_at_speed += sim_s / speed
            self.wall_s += wall_s

    def report(self, speed: float) -> dict:
        """`rtf`: sim seconds per wall second over the paced stretches; `rtf_error`: how far the wall time they took
        was from what the speed asked (negative: slower); `sim_tick_late_ms`: each tick's start after it was due."""
        rtf = self.sim_s / self.wall_s if self.wall_s > 0 else None
        error = self.sim_s_at_speed / self.wall_s - 1.0 if self.wall_s > 0 else None
        return {
            "speed": speed,
            "paced_sim_s": round(self.sim_s, 3),
            "rtf": None if rtf is None else round(rtf, 4),
            "rtf_error": None if error is None else round(error, 4) + 0.0,  # never -0.0
            "sim_tick_late_ms": spread_ms(self.late_ms),
        }


class RealtimePacing:
    """The sim's clock held to the wall clock at the speed factor, from when every process answered (and again after
    a pause or a change of speed). Handed what it reads each tick: the sim's time, the speed factor and whether every
    process answered (`settings`), how to wait while answers may arrive, the wall-time counts it adds its waits to,
    and the `figures` it measures into."""

    def __init__(
        self,
        sim_time_s: Callable[[], float],
        settings: Callable[[], tuple[float, bool]],
        wait: Callable[[float], None],
        wall_s: Counter,
        figures: ClockFigures | None = None,
    ) -> None:
        self._sim_time_s, self._settings, self._wait, self._wall_s = sim_time_s, settings, wait, wall_s
        self.figures = figures if figures is not None else ClockFigures()
        self.wall, self.sim, self.speed, self.started = time.monotonic(), sim_time_s(), 1.0, False
        self.restart()

    def restart(self, measure: bool = True) -> None:
        """The clock goes on from here; the stretch since the last restart is measured if it was paced (and
        `measure`: not the wall time a snapshot stood the line still for)."""
        now, sim = time.monotonic(), self._sim_time_s()
        if self.started and measure:
            self.figures.stretch(sim - self.sim, now - self.wall, self.speed)
        self.wall, self.sim = now, sim
        self.speed, self.started = self._settings()

    def wait(self) -> None:
        """Until the wall clock catches up with the sim's at the speed factor; the next tick's lateness noted."""
        if self._settings() != (self.speed, self.started):  # the clock starts once every process answered
            self.restart()
        due = self.wall + (self._sim_time_s() - self.sim) / self.speed
        ahead = due - time.monotonic()
        if ahead > 0:
            self._wait(ahead)  # answers that arrive meanwhile are applied at the next tick
            self._wall_s["pacing"] += ahead
        if self.started:
            self.figures.late_ms.append(max(0.0, time.monotonic() - due) * 1000.0)

    def close(self) -> None:
        """The run's last stretch, measured."""
        self.restart()
