"""What the monitor knows of a running line: the latest message of each kind, read from the bus.

Subscriber callbacks only keep each key's newest payload (a page redrawn at 30 Hz
has no use for the other 70 states an arm publishes per second); `take()` decodes
them once per frame. Malformed payloads are dropped and counted like everywhere else.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import zenoh

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState, Assignment, PartsState, Progress, Separations, SimStatus


@dataclass
class LineSnapshot:
    """The line as last heard: per-arm states and assignments (by arm id), and the latest of each line-wide message."""

    arms: dict[str, ArmState] = field(default_factory=dict)
    assignments: dict[str, Assignment] = field(default_factory=dict)
    parts: PartsState | None = None
    separations: Separations | None = None
    progress: Progress | None = None
    status: SimStatus | None = None

    @property
    def sim_time_s(self) -> float:
        return self.status.sim_time_s if self.status else (self.parts.sim_time_s if self.parts else 0.0)


class LatestPayloads:
    """A subscriber callback keeping only the newest payload of each key (thread-safe, no decoding)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._latest: dict[str, bytes] = {}
        self.received = 0

    def __call__(self, sample: zenoh.Sample) -> None:
        payload = sample.payload.to_bytes()
        with self._lock:
            self._latest[str(sample.key_expr)] = payload
            self.received += 1

    def take(self) -> dict[str, bytes]:
        """The newest payload of every key heard since the last call."""
        with self._lock:
            latest, self._latest = self._latest, {}
        return latest


class LiveFeed:
    """Subscribes to everything the page draws; use in a `with` block so the subscribers are undeclared."""

    def __init__(self, session: zenoh.Session, keys: Keys) -> None:
        self.keys = keys
        self.drops = DropCounter()
        self.snapshot = LineSnapshot()
        self._payloads = LatestPayloads()
        self._decoders = {
            "state": Decoder(ArmState, self.drops), "assign": Decoder(Assignment, self.drops),
            keys.parts: Decoder(PartsState, self.drops), keys.coord("separation"): Decoder(Separations, self.drops),
            keys.coord("progress"): Decoder(Progress, self.drops), keys.sim_status: Decoder(SimStatus, self.drops),
        }
        watched = [keys.all_arms("state"), keys.all_arms("assign"), keys.parts, keys.coord("separation"), keys.coord("progress"), keys.sim_status]
        self._subs = [session.declare_subscriber(k, self._payloads) for k in watched]

    def __enter__(self) -> "LiveFeed":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        self._subs = []

    @property
    def received(self) -> int:
        return self._payloads.received

    def take(self) -> LineSnapshot:
        """The snapshot updated with everything new; messages for arms of another scene are dropped."""
        snap = self.snapshot
        for key, payload in self._payloads.take().items():
            leaf = key.rsplit("/", 1)[-1]
            decoder = self._decoders.get(leaf) if leaf in ("state", "assign") else self._decoders.get(key)
            if decoder is None:
                continue
            msg = decoder.decode(key, payload)
            if msg is None:
                continue
            if isinstance(msg, ArmState):
                snap.arms[msg.arm] = msg
            elif isinstance(msg, Assignment):
                snap.assignments[msg.arm] = msg
            elif isinstance(msg, PartsState):
                snap.parts = msg
            elif isinstance(msg, Separations):
                snap.separations = msg
            elif isinstance(msg, Progress):
                snap.progress = msg
            elif isinstance(msg, SimStatus):
                snap.status = msg
        return snap

