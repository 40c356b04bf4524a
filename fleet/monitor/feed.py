"""What the monitor knows of a running line: the latest message of each kind, read from the bus.

Arms and parts come from the sim's `LineView` (all of them in one message, 25 times per
sim second, built only while someone watches) rather than the per-arm states at the control
rate. Each key gets a subscriber whose queue holds one sample (Zenoh's ring channel): older
samples are dropped inside Zenoh without waking Python. `take()` reads
what is there once per frame. Malformed payloads are dropped and counted like everywhere else.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import zenoh

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.message_checks import progress_problem, sim_status_problem
from fleet.bus.messages import ArmOrder, ArmState, Assignment, LineView, PartsState, Progress, Separations, SimStatus


@dataclass
class LineSight:
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


class LiveFeed:
    """Subscribes to everything the page draws; use in a `with` block so the subscribers are undeclared."""

    def __init__(self, session: zenoh.Session, keys: Keys, arms: list[str]) -> None:
        self.keys, self.arms = keys, list(arms)
        self.drops = DropCounter()
        self.sight = LineSight()
        self.taken = 0
        # an arm's orders are assignments and motion grants on one key: both are the coordinator's, the view shows
        # assignments
        watched: list[tuple[str, type]] = [(keys.view, LineView)] + [(keys.arm_assign(a), ArmOrder) for a in arms]
        watched += [
            (keys.coord("separation"), Separations),
            (keys.coord("progress"), Progress),
            (keys.sim_status, SimStatus),
        ]
        self._subs = [
            (session.declare_subscriber(k, zenoh.handlers.RingChannel(1)), k, Decoder(t, self.drops))
            for k, t in watched
        ]

    def __enter__(self) -> LiveFeed:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        for sub, _, _ in self._subs:
            sub.undeclare()
        self._subs = []

    def _implausible(self, msg: object) -> str:
        """Why a progress report or sim status cannot be true of the line watched ("": it can)."""
        if isinstance(msg, Progress):
            return progress_problem(msg, len(self.arms))
        if isinstance(msg, SimStatus):
            return sim_status_problem(msg, self.arms)
        return ""

    def take(self) -> LineSight:
        """The sight updated with the newest sample of every key heard since the last call."""
        snap = self.sight
        for sub, key, decoder in self._subs:
            sample = sub.try_recv()
            if sample is None:
                continue
            self.taken += 1
            msg = decoder.decode(key, sample.payload.to_bytes())
            problem = self._implausible(msg)
            if problem:
                self.drops.drop(key, problem)
            elif isinstance(msg, LineView):
                snap.arms.update((a.arm, a) for a in msg.arms)
                snap.parts = msg.parts
            elif isinstance(msg, Assignment):
                snap.assignments[msg.arm] = msg
            elif isinstance(msg, Separations):
                snap.separations = msg
            elif isinstance(msg, Progress):
                snap.progress = msg
            elif isinstance(msg, SimStatus):
                snap.status = msg
        return snap
