"""The coordinator's parts when the line works from its cameras (`--perception cameras`): perception's `PartsState`
messages, one a frame tick, and for each decision the newest frame usable at its tick; how old those parts were."""

from __future__ import annotations

from collections import deque

import numpy as np

from coordinator.allocation import PartView
from fleet.bus.messages import PartsState
from fleet.sight.line_sight import carried_to, newest_up_to, seen_parts_problem
from fleet.sight.part_views import part_views
from perception.seen_ticks import SeenTicks

NEWEST_SEEN = 64  # frames' parts kept (a decision works from the newest usable at its tick)


class SeenParts:
    """Perception's parts (`take`), believed only at a frame tick of `ticks`; `ready(tick)` says whether a decision
    at `tick` has its frame in, `views(tick)` gives its parts."""

    def __init__(self, ticks: SeenTicks) -> None:
        self.ticks, self.control_hz = ticks, ticks.control_hz
        self.frames: deque[PartsState] = deque(maxlen=NEWEST_SEEN)
        self.ages_ticks: list[int] = []  # per decision: its tick less its frame's
        self.late = 0  # decisions made without their frame (perception silent or slow)

    def problem(self, msg: PartsState) -> str:
        """Why a decoded parts message cannot be perception's ("" if it can)."""
        return seen_parts_problem(msg, self.ticks)

    def take(self, msg: PartsState) -> None:
        if not self.frames or msg.tick > self.frames[-1].tick:
            self.frames.append(msg)

    def ready(self, tick: int) -> bool:
        needed = self.ticks.usable_at(tick)
        return needed < 0 or (bool(self.frames) and self.frames[-1].tick >= needed)

    def views(self, tick: int) -> tuple[dict[int, PartView], float]:
        """The parts of the newest frame usable at `tick` (none before the first), carried to `tick` by their motion,
        and the sim time of `tick`."""
        needed = self.ticks.usable_at(tick)
        newest = newest_up_to(self.frames, needed)
        if newest is None:
            self.late += needed >= 0
            return {}, tick / self.control_hz
        self.late += newest.tick != needed
        self.ages_ticks.append(tick - newest.tick)
        frame = carried_to(newest, tick, self.control_hz)
        return part_views(frame), frame.sim_time_s

    def report(self, control_hz: float, frame_s: float) -> dict:
        """How old the parts decisions worked from were (p50, p95: ms and frames), and how many went without."""
        ages_s = np.asarray(self.ages_ticks, float) / control_hz
        out = {"decisions": len(self.ages_ticks), "decisions_without_their_frame": self.late}
        for q in (50, 95):
            age = float(np.percentile(ages_s, q)) if len(ages_s) else float("nan")
            out[f"latency_p{q}_ms"] = round(1000.0 * age, 1)
            out[f"latency_p{q}_frames"] = round(age / frame_s, 2)
        return out
