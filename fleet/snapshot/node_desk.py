"""A node's side of a run's snapshots: the sim's asks queued (the callback only queues), the node's part sent once it
has everything the ask names, and "I am back" answered by a node started from a snapshot.

The node owns the decision of when it is ready (`ready`) and what its state is (`capture`); the desk owns the bus.
"""

from __future__ import annotations

import threading
import zlib
from collections.abc import Callable

import zenoh

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.messages import SnapshotAsk, SnapshotPart
from fleet.bus.session import Inbox
from fleet.snapshot.process_state import StateError


class SnapshotDesk:
    """Snapshot asks for one node (`coordinator` or an arm id; `role` the ask's `node` it answers)."""

    def __init__(
        self,
        session: zenoh.Session,
        keys: Keys,
        node: str,
        role: str,
        drops: DropCounter,
        wake: threading.Event | None = None,
        incarnation: Callable[[], int] = lambda: 0,
    ) -> None:
        self.node, self.role, self.incarnation = node, role, incarnation
        self.inbox = Inbox(wake=wake) if wake is not None else Inbox()
        self._decoder = Decoder(SnapshotAsk, drops)
        self._sub = session.declare_subscriber(keys.snapshot_ask, self.inbox)
        self._pub = session.declare_publisher(keys.snapshot_part(node))
        self.pending: SnapshotAsk | None = None
        self.restored_tick: int | None = None  # set by a node started from a snapshot, once it is back
        self._sent: tuple[SnapshotAsk, bytes] | None = None  # the last part sent: asked again, it goes again

    def serve(
        self,
        ready: Callable[[SnapshotAsk], bool],
        capture: Callable[[SnapshotAsk], tuple[bytes, tuple]],
        restore: Callable[[bytes], None],
    ) -> bool:
        """Handle the asks queued: "are you back" answered, a part sent once `ready(ask)` (its state and orders from
        `capture(ask)`), then the node put back to what it wrote (`restore`: it goes on exactly as a node restored
        from it will; after sending, so the sim does not wait for it). True when a part was made now."""
        for key, payload in self.inbox.drain():
            ask = self._decoder.decode(key, payload)
            if ask is None:
                continue
            if ask.node == "restored":
                if self.restored_tick == ask.tick:
                    self._pub.put(encode(SnapshotPart(self.node, ask.tick, restored=True)))
            elif ask.node == self.role:
                if self._sent is not None and self._sent[0] == ask:
                    self._pub.put(self._sent[1])  # the sim asks again: it missed the part
                else:
                    self.pending = ask  # a new ask (or the same tick's, naming more orders: made again)
        if self.pending is None or not ready(self.pending):
            return False
        ask, self.pending = self.pending, None
        state = b""
        try:
            state, orders = capture(ask)
            part = SnapshotPart(
                self.node, ask.tick, zlib.compress(state, 1), orders=orders, incarnation=self.incarnation()
            )
        except StateError as exc:
            part = SnapshotPart(self.node, ask.tick, error=str(exc)[:400])
        payload = encode(part)
        self._sent = (ask, payload)
        self._pub.put(payload)
        if state:
            restore(state)
        return True

    def use_drops(self, drops: DropCounter) -> None:
        """Count malformed asks in `drops` (a node's counter, put back from a snapshot)."""
        self._decoder.drops = drops

    def back(self, tick: int) -> None:
        """A node started from the snapshot of `tick` has put its state back: say so (and whenever asked)."""
        self.restored_tick = tick
        self._pub.put(encode(SnapshotPart(self.node, tick, restored=True)))

    def close(self) -> None:
        self._sub.undeclare()
        self._pub.undeclare()
