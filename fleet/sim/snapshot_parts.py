"""A lockstep snapshot's parts, gathered while the line goes on (one concern of `SimSnapshots`, kept apart), and
what taking it cost the ticks after it.

The sim asks at the tick boundary and goes on: each node, told of the boundary ahead, writes its state as of it,
holding back whatever the line sends it from then on (`fleet.snapshot.snapshot_link`), and its part arrives while the
next ticks run. So the line stands still only for the sim's own state; the nodes' writing shows up as later answers
in the ticks after the cut, which `CostDue` measures against the same number of ticks before it (the median of a
few such runs of ticks: one alone may hold a long decision).
"""

from __future__ import annotations

import statistics
import time
from collections import deque
from dataclasses import dataclass, field

from fleet.bus.codec import Decoder
from fleet.bus.messages import SnapshotAsk, SnapshotPart
from fleet.sim.snapshot_asks import ASK_AGAIN_S, NODE_TIMEOUT_S, SnapshotFailed, part_of, publish_asks, take_parts

BASELINE_WINDOWS = 5  # runs of ticks before a cut whose median wall time the ticks after it are measured against


@dataclass
class PartsDue:
    """The parts of the snapshot of `asks[0].tick` still to come from `nodes` (the coordinator first, then the arms
    in the scene's order), asked again every `ASK_AGAIN_S` (a part may be lost on the way) until `NODE_TIMEOUT_S`."""

    sim: object
    asks: list[SnapshotAsk]
    nodes: list[str]
    alive: dict[str, int] = field(default_factory=dict)  # the start of each node running at the cut (the roster's)
    got: dict[str, SnapshotPart] = field(default_factory=dict)
    asked_at: float = field(default_factory=time.monotonic)
    deadline: float = 0.0

    def __post_init__(self) -> None:
        self.deadline = self.asked_at + NODE_TIMEOUT_S
        self._publish()

    def _publish(self) -> None:
        publish_asks(self.sim, self.asks)
        self.asked_at = time.monotonic()

    @property
    def tick(self) -> int:
        return self.asks[0].tick

    @property
    def complete(self) -> bool:
        return len(self.got) == len(self.nodes)

    def take_arrived(self) -> None:
        """The parts arrived so far kept (another tick's, or a restored node's, passed over); asked again when
        due. A node that answers it has no state fails the snapshot (`SnapshotFailed`)."""
        take_parts(self.sim, Decoder(SnapshotPart, self.sim.drops), self.nodes, part_of(self.asks), self.got)
        if not self.complete and time.monotonic() - self.asked_at > ASK_AGAIN_S:
            self._publish()

    def wait(self) -> None:
        """Until every part is in (`SnapshotFailed` if one is not within the time a node has, or the sim stops)."""
        while True:
            self.take_arrived()
            if self.complete:
                return
            stopping = self.sim.stop is not None and self.sim.stop.should_stop()
            if stopping or time.monotonic() > self.deadline:
                silent = [n for n in self.nodes if n not in self.got]
                raise SnapshotFailed(f"{', '.join(silent)} sent no state within {NODE_TIMEOUT_S:g} s")
            self.sim.bus.snapshot_inbox.wait(0.005)

    def parts(self) -> dict[str, SnapshotPart]:
        """Every part, once complete. A part from another start of its node than the one running at the cut (a
        replacement started since) fails the snapshot, as does a controller holding fewer orders than the
        coordinator says it sent it (the two would not agree on what was sent: it cannot be asked again, it has gone
        on)."""
        check_starts(self.got, self.alive)
        coordinator, arms = self.got["coordinator"], self.nodes[1:]
        behind = [a for i, a in enumerate(arms) if self.got[a].orders[:1] < coordinator.orders[i : i + 1]]
        if behind:
            raise SnapshotFailed(f"{', '.join(behind)} had not every order the coordinator sent when asked")
        return self.got


@dataclass
class NextTicks:
    """The wall time at each of the last `keep` + 1 tick boundaries: what a run of ticks took."""

    keep: int
    walls: deque = field(default_factory=deque)

    def at_boundary(self) -> None:
        self.walls.append(time.perf_counter())
        while len(self.walls) > self.keep + 1:
            self.walls.popleft()

    def before_s(self, span: int) -> float | None:
        """The median wall time of the last few runs of `span` ticks (up to `BASELINE_WINDOWS`; None: the run has
        not run `span` ticks yet)."""
        walls = self.walls
        runs = min(BASELINE_WINDOWS, (len(walls) - 1) // span)
        if runs < 1:
            return None
        return statistics.median(walls[-1 - k * span] - walls[-1 - (k + 1) * span] for k in range(runs))


@dataclass
class CostDue:
    """What one snapshot cost the line beyond its stall, still being measured: the wall time of the `span` ticks
    from the line going on again (`resumed`) less what `span` ticks took before the cut (`before_s`); `span` the
    ticks within which every node answers something sent after the cut (its part written first)."""

    tick: int
    span: int
    before_s: float | None
    resumed: float = field(default_factory=time.perf_counter)

    def extra_s(self, tick: int, ended: bool = False) -> float | None:
        """The extra wall time once `span` ticks ran, or the run `ended` (as far as it went); else None."""
        if tick - self.tick < self.span and not ended:
            return None
        if self.before_s is None:
            return 0.0
        ran = max(1, min(tick - self.tick, self.span))
        return max(0.0, time.perf_counter() - self.resumed - self.before_s * ran / self.span)


def check_starts(parts: dict[str, SnapshotPart], alive: dict[str, int]) -> None:
    """`SnapshotFailed` where a node's part came from another start of it than the one running at the cut (`alive`,
    from the launcher's roster): a replacement started since has no state of that tick boundary."""
    other = [
        f"{node}'s part came from its start {part.incarnation}, not start {alive[node]}, which ran at the cut"
        for node, part in parts.items()
        if node in alive and part.incarnation != alive[node]
    ]
    if other:
        raise SnapshotFailed("; ".join(other))


@dataclass
class NodeStarts:
    """Which start of each node runs, as the launcher's rosters heard so far say (none on a line without one)."""

    started: dict[str, int] = field(default_factory=dict)

    def now(self, bus) -> dict[str, int]:
        """The starts, with the rosters queued on `bus` (`SimBus.roster_inbox`) heard first."""
        for key, payload in bus.roster_inbox.drain():
            roster = bus.roster.decode(key, payload)
            if roster is not None and len(roster.nodes) == len(roster.incarnations):
                self.started.update(zip(roster.nodes, roster.incarnations))
        return dict(self.started)
