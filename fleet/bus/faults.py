"""Network faults on the bus, injected in one place: the sim server's links to each controller and to the coordinator.

A link has two directions: `down` (the sim's states and frames out) and `up` (answers, goals and the
coordinator's ticks in). Every message crossing it draws, from the link's own seeded stream, whether it
is lost and how long it travels: the latency plus normal jitter, clipped at zero, so a message can
overtake an earlier one. The clock is the caller's: sim seconds in lockstep (a seed repeats exactly),
wall seconds in realtime. Linux netem is not at hand on every machine, and a fault injected here is
the same in both clocks; `docs/running.md` says what a receiver does with a late, lost or overtaken message.
"""

from __future__ import annotations

import argparse
import heapq
import math
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
from pydantic import ValidationError

from robots.saved_state import SavedState, generator_of, generator_state
from scenes.schema import LinkFaults, Network

STREAM = 0xFA017  # the faults' own random stream beside the feeders' and the randomisation's, from the run's seed
DIRECTIONS = ("down", "up")


@dataclass(frozen=True)
class Passage:
    """One message's fate on a link: lost, or arriving `delay_s` after it was sent."""

    lost: bool
    delay_s: float


class FaultyLinkState(SavedState, frozen=True):
    """What a `FaultyLink` saves: its faults (a run restored keeps those of the run that took the snapshot), its counts
    and where each direction's random stream stands."""

    latency_ms: float
    jitter_ms: float
    loss: float
    counts: dict[str, int]
    delay_s_total: dict[str, float]
    streams: dict[str, str]  # direction -> its generator's state (`generator_state`)


@dataclass
class FaultyLink:
    """One link's faults and what they did; `passage` draws a message's fate."""

    name: str
    faults: LinkFaults
    seed: int
    index: int
    counts: Counter = field(default_factory=Counter)  # "<direction>_sent", "_lost", "_overtaken", "_stale"
    delay_s_total: Counter = field(default_factory=Counter)

    def __post_init__(self) -> None:
        self._rngs = {d: np.random.default_rng([self.seed, STREAM, self.index, i]) for i, d in enumerate(DIRECTIONS)}

    @property
    def active(self) -> bool:
        return self.faults.active

    def passage(self, direction: str) -> Passage:
        """The fate of the next message sent `direction` ("down" or "up") on this link."""
        self.counts[f"{direction}_sent"] += 1
        if not self.active:
            return Passage(False, 0.0)
        rng, f = self._rngs[direction], self.faults
        lost = bool(rng.random() < f.loss)
        delay_s = max(0.0, f.latency_ms + (rng.normal(0.0, f.jitter_ms) if f.jitter_ms > 0 else 0.0)) / 1e3
        if lost:
            self.counts[f"{direction}_lost"] += 1
        else:
            self.delay_s_total[direction] += delay_s
        return Passage(lost, delay_s)

    def note(self, direction: str, what: str) -> None:
        """Count a message the receiver dropped: `overtaken` by a newer one, or `stale` (older than one applied)."""
        self.counts[f"{direction}_{what}"] += 1

    def state(self) -> FaultyLinkState:
        f = self.faults
        return FaultyLinkState(
            latency_ms=f.latency_ms,
            jitter_ms=f.jitter_ms,
            loss=f.loss,
            counts=dict(self.counts),
            delay_s_total=dict(self.delay_s_total),
            streams={d: generator_state(rng) for d, rng in self._rngs.items()},
        )

    def restore(self, state: FaultyLinkState) -> None:
        self.faults = LinkFaults(latency_ms=state.latency_ms, jitter_ms=state.jitter_ms, loss=state.loss)
        self.counts, self.delay_s_total = Counter(state.counts), Counter(state.delay_s_total)
        self._rngs = {d: generator_of(s) for d, s in state.streams.items()}

    def report(self) -> dict:
        """What was injected on this link and what it did."""
        out: dict = {"latency_ms": self.faults.latency_ms, "jitter_ms": self.faults.jitter_ms, "loss": self.faults.loss}
        for d in DIRECTIONS:
            arrived = self.counts[f"{d}_sent"] - self.counts[f"{d}_lost"]
            out[d] = {k.split("_", 1)[1]: v for k, v in sorted(self.counts.items()) if k.startswith(d + "_")}
            out[d]["mean_delay_ms"] = round(1e3 * self.delay_s_total[d] / arrived, 3) if arrived else 0.0
        return out


def ticks_for(delay_s: float, hz: float) -> int:
    """Whole ticks a delay takes in lockstep: rounded up, so a message never lands before its delay has passed."""
    return max(0, math.ceil(delay_s * hz - 1e-9))


def links_for(network: Network | None, names: list[str], seed: int) -> dict[str, FaultyLink]:
    """A `FaultyLink` for each of `names` (arms, then `coordinator`), with its faults from the scene's `network`."""
    network = network or Network()
    return {name: FaultyLink(name, network.link(name), seed, i) for i, name in enumerate(names)}


def faults_report(links: dict[str, FaultyLink]) -> dict:
    """The run summary's `network_faults`: per link what was injected and what it did (empty without faults)."""
    return {name: link.report() for name, link in links.items() if link.active and link.counts}


class DelayLine:
    """Realtime: messages held until their wall time of arrival, then handed back in arrival order."""

    def __init__(self) -> None:
        self._heap: list = []
        self._count = 0

    def push(self, due_s: float, item: object) -> None:
        heapq.heappush(self._heap, (due_s, self._count, item))
        self._count += 1

    def pop_due(self, now_s: float) -> list:
        out = []
        while self._heap and self._heap[0][0] <= now_s:
            out.append(heapq.heappop(self._heap)[2])
        return out

    def __len__(self) -> int:
        return len(self._heap)

    def held(self) -> list[tuple[float, int, object]]:
        """What is held, in heap order: (due wall time, arrival order, item)."""
        return list(self._heap)

    def put_back(self, held: list[tuple[float, int, object]], count: int) -> None:
        """Hold again what `held` said, numbering on from `count`."""
        self._heap, self._count = list(held), count
        heapq.heapify(self._heap)

    @property
    def count(self) -> int:
        return self._count


def add_fault_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags that put faults on every link (replacing the scene's `network`)."""
    group = parser.add_argument_group("network faults (every link between the sim and the other processes, each way)")
    group.add_argument(
        "--latency-ms", type=float, default=None, metavar="MS", help="mean one-way delay (sim time in lockstep)"
    )
    group.add_argument(
        "--jitter-ms",
        type=float,
        default=None,
        metavar="MS",
        help="standard deviation of the delay (messages may overtake)",
    )
    group.add_argument(
        "--loss", type=float, default=None, metavar="P", help="probability that a message is lost, 0 to 1"
    )


def network_from_args(args: argparse.Namespace) -> Network | None:
    """The `Network` the fault flags ask for (None when none is given); ValueError names the flag at fault."""
    given = {k: getattr(args, k, None) for k in ("latency_ms", "jitter_ms", "loss")}
    if all(v is None for v in given.values()):
        return None
    values = {k: v for k, v in given.items() if v is not None}
    try:
        return Network(**values)
    except ValidationError as exc:
        err = exc.errors()[0]
        flag = "--" + str(err["loc"][0]).replace("_", "-")
        raise ValueError(f"{flag} {values[err['loc'][0]]:g}: {err['msg']}") from None
