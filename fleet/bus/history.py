"""The line's event log on the bus: the sim answers `Keys.history` with every line event so far (`EventLog`);
a coordinator that takes over a running line (respawned after a crash) asks, and rebuilds its ledger from it."""

from __future__ import annotations

from collections.abc import Callable

import zenoh

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.messages import EventLog
from fleet.bus.query import first_answer


class HistoryUnavailable(RuntimeError):
    """No sim answered the history query in time."""


def serve_history(session: zenoh.Session, keys: Keys, log: Callable[[], EventLog]) -> zenoh.Queryable:
    """Answer history queries with `log()` (called on Zenoh's thread: it must only copy) until undeclared."""
    return session.declare_queryable(keys.history, lambda query: query.reply(keys.history, encode(log())))


def fetch_history(session: zenoh.Session, keys: Keys, drops: DropCounter, timeout_s: float = 30.0) -> EventLog:
    """The event log the running sim serves, asked until it answers or `timeout_s` passes; a reply that does not
    decode is dropped and counted (`drops`) and the next one taken."""
    decoder = Decoder(EventLog, drops)
    log = first_answer(
        session, keys.history, lambda payload: decoder.decode(keys.history, payload), timeout_s, per_query_s=2.0
    )
    if log is None:
        raise HistoryUnavailable(f"no sim of run {keys.run!r} answered on {keys.history} within {timeout_s:.0f} s")
    return log
