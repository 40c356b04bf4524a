"""What the sim server counts over a run, and the parts of the run summary those counts give."""

from __future__ import annotations

from collections import Counter, deque
from dataclasses import dataclass, field

import numpy as np

from robots.saved_state import SavedState

RTT_EDGES_MS = np.geomspace(0.05, 2000.0, 47)  # log-spaced: sub-millisecond loopback to a lockstep timeout


class StatsState(SavedState, frozen=True):
    """What `SimStats` saves: every count, as it stands."""

    watchdog_holds: dict[str, int]
    lost: list[str]
    rejoined: list[str]
    ticks: int
    contact_ticks: int
    contact_pairs: list[tuple[str, str]]
    round_trip_ms: list[float]
    coordinator_lost: bool
    wall_s: dict[str, float]
    busy_ticks: dict[str, int]
    grant_wait_ticks: dict[str, int]
    recent_round_trip_ms: list[float]
    last_contact_pairs: tuple[str, ...]
    last_contact_s: float
    results: dict[str, int]
    messages_out: dict[str, int]
    messages_in: dict[str, int]


COUNTERS = ("watchdog_holds", "wall_s", "busy_ticks", "grant_wait_ticks", "results", "messages_out", "messages_in")


@dataclass
class SimStats:
    """The sim server's counts; `summary` turns them into the run summary's figures."""

    watchdog_holds: Counter = field(default_factory=Counter)
    lost: list[str] = field(default_factory=list)
    rejoined: list[str] = field(default_factory=list)
    ticks: int = 0
    contact_ticks: int = 0
    contact_pairs: set = field(default_factory=set)
    round_trip_ms: list[float] = field(default_factory=list)
    coordinator_lost: bool = False
    wall_s: Counter = field(default_factory=Counter)  # where the server's wall time went, by stage
    busy_ticks: Counter = field(default_factory=Counter)  # ticks each arm's controller reported a running skill
    grant_wait_ticks: Counter = field(default_factory=Counter)  # of those, ticks it held still for a motion grant
    recent_round_trip_ms: deque = field(default_factory=lambda: deque(maxlen=1000))
    last_contact_pairs: tuple[str, ...] = ()
    last_contact_s: float = -1.0
    results: Counter = field(default_factory=Counter)  # goal results by status
    messages_out: Counter = field(default_factory=Counter)  # published, by key leaf
    messages_in: Counter = field(default_factory=Counter)  # received, by key leaf

    def state(self) -> StatsState:
        return StatsState(
            **{name: dict(getattr(self, name)) for name in COUNTERS},
            lost=list(self.lost),
            rejoined=list(self.rejoined),
            ticks=self.ticks,
            contact_ticks=self.contact_ticks,
            contact_pairs=sorted(self.contact_pairs),
            round_trip_ms=list(self.round_trip_ms),
            coordinator_lost=self.coordinator_lost,
            recent_round_trip_ms=list(self.recent_round_trip_ms),
            last_contact_pairs=self.last_contact_pairs,
            last_contact_s=self.last_contact_s,
        )

    def restore(self, state: StatsState) -> None:
        for name in COUNTERS:  # in place: what counts into them (the realtime pacing) keeps doing so
            counter = getattr(self, name)
            counter.clear()
            counter.update(getattr(state, name))
        self.lost, self.rejoined = list(state.lost), list(state.rejoined)
        self.ticks, self.contact_ticks = state.ticks, state.contact_ticks
        self.contact_pairs = {tuple(p) for p in state.contact_pairs}
        self.round_trip_ms, self.coordinator_lost = list(state.round_trip_ms), state.coordinator_lost
        self.recent_round_trip_ms = deque(state.recent_round_trip_ms, maxlen=self.recent_round_trip_ms.maxlen)
        self.last_contact_pairs, self.last_contact_s = tuple(state.last_contact_pairs), state.last_contact_s

    def round_trip(self, rtt_ms: float) -> None:
        """A state's answer came back `rtt_ms` after the state was delivered."""
        self.round_trip_ms.append(rtt_ms)
        self.recent_round_trip_ms.append(rtt_ms)

    def contacts(self, pairs: set[tuple[str, str]], sim_time_s: float) -> None:
        """The pairs of arms touching at this tick (none: nothing to note)."""
        if pairs:
            self.contact_ticks += 1
            self.contact_pairs.update(pairs)
            self.last_contact_pairs = tuple(sorted("-".join(p) for p in pairs))
            self.last_contact_s = sim_time_s

    def arm_time(self, arm: str) -> dict[str, float]:
        """Fractions of the run an arm worked, held still waiting for a motion grant, or had no task."""
        ticks = max(self.ticks, 1)
        busy, waiting = self.busy_ticks[arm], self.grant_wait_ticks[arm]
        return {
            "working": round((busy - waiting) / ticks, 4),
            "waiting_for_grant": round(waiting / ticks, 4),
            "idle": round(1 - busy / ticks, 4),
        }

    def messages_per_arm_per_s(self, arms: int, sim_s: float) -> dict[str, float]:
        """Bus messages per arm per sim second, by key leaf, both ways (the sim's own count)."""
        sim_s, arms = max(sim_s, 1e-9), max(arms, 1)
        both = self.messages_out + self.messages_in
        return {k: round(v / arms / sim_s, 2) for k, v in sorted(both.items())}

    def summary(self, arms: list[str], sim_s: float) -> dict:
        """The run summary's figures that come from these counts alone."""
        rtt = np.asarray(self.round_trip_ms)
        return {
            "utilisation": {a: round(self.busy_ticks[a] / self.ticks, 4) if self.ticks else 0.0 for a in arms},
            "arm_time": {a: self.arm_time(a) for a in arms},
            "inter_arm_contacts": self.contact_ticks,
            "contact_pairs": sorted("-".join(p) for p in self.contact_pairs),
            "latency_p50_ms": round(float(np.percentile(rtt, 50)), 3) if rtt.size else None,
            "latency_p99_ms": round(float(np.percentile(rtt, 99)), 3) if rtt.size else None,
            "round_trip_histogram": round_trip_histogram(rtt),
            "messages_out": dict(sorted(self.messages_out.items())),
        }

    def outcome(self, arms: list[str], sim_s: float) -> dict:
        """The summary's figures on goals, holds, lost arms and messages."""
        return {
            "goal_results": dict(sorted(self.results.items())),
            "watchdog_holds": dict(self.watchdog_holds),
            "arms_lost": list(self.lost),
            "arms_rejoined": list(self.rejoined),
            "coordinator_lost": self.coordinator_lost,
            "bus_messages_per_arm_per_s": self.messages_per_arm_per_s(len(arms), sim_s),
        }

    def wall_clock(self) -> dict:
        """Where the server's wall time went."""
        return {
            "wall_s_by_stage": {k: round(v, 3) for k, v in self.wall_s.items()},
            "loop_wall_seconds": round(sum(v for k, v in self.wall_s.items() if k != "startup"), 3),
        }


def round_trip_histogram(rtt_ms: np.ndarray) -> dict:
    """Every state-to-answer round trip of the run, binned (log-spaced edges in ms)."""
    counts, _ = np.histogram(np.clip(rtt_ms, RTT_EDGES_MS[0], RTT_EDGES_MS[-1]), bins=RTT_EDGES_MS)
    return {"edges_ms": [round(float(e), 4) for e in RTT_EDGES_MS], "counts": counts.tolist()}
