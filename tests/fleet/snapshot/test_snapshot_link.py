"""A node's link holds what the line sends from the tick of a snapshot it was told of, until its part of that one is
sent: a snapshot asked for at once before it (the monitor's button) is answered without letting go."""

import time

import msgspec

from fleet.bus.codec import DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.messages import SnapshotAsk, SnapshotPart
from fleet.bus.session import BusEndpoints, Hold, Inbox, open_session
from fleet.snapshot.cut import Cut
from fleet.snapshot.snapshot_link import SnapshotLink


def _later(key: str, payload: bytes, cut: Cut) -> bool:
    return int(payload) >= cut.tick


def _answer(link: SnapshotLink, parts: Inbox, tick: int) -> None:
    """Serve the link until its part for `tick` is on the bus."""
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        link.serve(lambda ask: True, lambda ask: (b"state", ()), lambda state: None)
        if any(msgspec.msgpack.decode(p, type=SnapshotPart).tick == tick for _, p in parts.drain()):
            return
        time.sleep(0.01)
    raise AssertionError(f"no part for tick {tick}")


def test_a_snapshot_asked_for_at_once_does_not_let_go_of_the_one_told():
    keys = Keys("snapshot_link")
    hold = Hold(_later)
    states, parts = Inbox(hold=hold), Inbox()
    with open_session(BusEndpoints()) as session:
        link = SnapshotLink(session, keys, "arm_0", "controllers", DropCounter(), hold=hold)
        asks = session.declare_publisher(keys.snapshot_ask)
        listener = session.declare_subscriber(keys.snapshot_part("arm_0"), parts)
        time.sleep(0.3)
        link.expect(600)  # a state said: the next snapshot is at tick 600
        hold.put(states, ("state", b"590"))
        hold.put(states, ("state", b"600"))
        assert [p for _, p in states.items] == [b"590"]
        asks.put(encode(SnapshotAsk(595, "controllers")))  # asked for at once, before the one told
        _answer(link, parts, 595)
        assert hold.holding and [p for _, p in states.items] == [b"590"], "still held for 600"
        asks.put(encode(SnapshotAsk(600, "controllers")))
        _answer(link, parts, 600)
        assert not hold.holding and [p for _, p in states.items] == [b"590", b"600"]
        listener.undeclare()
        link.close()
