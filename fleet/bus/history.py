"""The line's event log on the bus: the sim answers `Keys.history` with every line event so far (`EventLog`);
a coordinator that takes over a running line (respawned after a crash) asks, and rebuilds its ledger from it."""

from __future__ import annotations

import time
from collections.abc import Callable

import zenoh

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.messages import EventLog


class HistoryUnavailable(RuntimeError):
    """No sim answered the history query in time."""


def serve_history(session: zenoh.Session, keys: Keys, log: Callable[[], EventLog]) -> zenoh.Queryable:
    """Answer history queries with `log()` (called on Zenoh's thread: it must only copy) until undeclared."""
    return session.declare_queryable(keys.history, lambda query: query.reply(keys.history, encode(log())))


def fetch_history(session: zenoh.Session, keys: Keys, drops: DropCounter, timeout_s: float = 30.0) -> EventLog:
    """The event log the running sim serves, asked until it answers or `timeout_s` passes; a reply that does not
    decode is dropped and counted (`drops`) and the next one taken."""
    decoder = Decoder(EventLog, drops)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for reply in session.get(keys.history, timeout=min(2.0, max(deadline - time.monotonic(), 0.1))):
            if reply.ok is not None:
                log = decoder.decode(keys.history, reply.ok.payload.to_bytes())
                if log is not None:
                    return log
        time.sleep(0.1)
    raise HistoryUnavailable(f"no sim of run {keys.run!r} answered on {keys.history} within {timeout_s:.0f} s")
