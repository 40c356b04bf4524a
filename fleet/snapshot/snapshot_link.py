"""A node's side of a run's snapshots: the sim's asks queued, the node's part sent once it has everything the ask
names, and "I am back" answered by a node started from a snapshot.

In lockstep the sim names the tick of the run's next snapshot in every state and frame it sends (`snapshot_tick`),
asks at that tick boundary and goes on without waiting for the parts: a node's state is its state as of the
boundary. So a node told of one (`expect`) holds back what the line sends it from that tick on
(`fleet.bus.session.Hold`: `fleet.snapshot.cut` says which messages those are) until its part is sent.

The node owns the decision of when it is ready (`ready`) and what its state is (`capture`); the link owns the bus.
"""

from __future__ import annotations

import threading
import time
import zlib
from collections.abc import Callable

import zenoh

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.messages import SnapshotAsk, SnapshotPart
from fleet.bus.session import Hold, Inbox
from fleet.snapshot.cut import Cut
from fleet.snapshot.process_state import StateError

READY_TIMEOUT_S = 10.0  # wall seconds a node waits for what an ask names before it answers that it cannot


class SnapshotLink:
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
        hold: Hold | None = None,
    ) -> None:
        """`hold`: the one the node's other inboxes share (held from the tick of a snapshot it is told of until its
        part is sent)."""
        self.node, self.role, self.incarnation, self.hold = node, role, incarnation, hold
        self.inbox = Inbox(wake=wake) if wake is not None else Inbox()
        self._decoder = Decoder(SnapshotAsk, drops)
        self._sub = session.declare_subscriber(keys.snapshot_ask, self.inbox)
        self._pub = session.declare_publisher(keys.snapshot_part(node))
        self.pending: SnapshotAsk | None = None
        self._pending_since = 0.0
        self.restored_tick: int | None = None  # set by a node started from a snapshot, once it is back
        self._sent: tuple[SnapshotAsk, bytes] | None = None  # the last part sent: asked again, it goes again
        self._expected = -1  # the tick of the snapshot this node holds for (-1: none)

    def expect(self, snapshot_tick: int) -> None:
        """A state or frame said the run's next snapshot is at `snapshot_tick` (-1: none): from that tick on, what
        arrives is held until this node's part of it is sent. Call as the message is handled (nothing of that tick
        can have been sent yet)."""
        answered = self._sent[0].tick if self._sent is not None else -1
        if self.restored_tick is not None:  # a state delayed on a faulty link may name the one it was restored from
            answered = max(answered, self.restored_tick)
        if self.hold is not None and snapshot_tick > max(answered, self._expected):
            self._expected = snapshot_tick
            self.hold.start(Cut(snapshot_tick))

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
                elif ask != self.pending:
                    self.pending = ask  # a new ask (or the same tick's, naming more orders: made again)
                    self._pending_since = time.monotonic()
        if self.pending is None:
            return False
        if not ready(self.pending):
            if time.monotonic() - self._pending_since < READY_TIMEOUT_S:
                return False
            self._answer(self.pending, error=f"not ready within {READY_TIMEOUT_S:g} s (what the ask names never came)")
            return True
        ask, self.pending = self.pending, None
        state = b""
        try:
            state, orders = capture(ask)
            part = SnapshotPart(
                self.node, ask.tick, zlib.compress(state, 1), orders=orders, incarnation=self.incarnation()
            )
        except StateError as exc:
            part = SnapshotPart(self.node, ask.tick, error=str(exc)[:400])
        self._send(ask, part)
        if state:
            restore(state)
        self._release(ask.tick)  # what arrived from the cut on, now handled from the state written
        return True

    def _answer(self, ask: SnapshotAsk, error: str) -> None:
        """No state for `ask`: say why, and stop holding."""
        self.pending = None
        self._send(ask, SnapshotPart(self.node, ask.tick, error=error[:400]))
        self._release(ask.tick)

    def _release(self, tick: int) -> None:
        """Stop holding, once the snapshot held for is answered (one asked for at once, before it, is not it)."""
        if tick < self._expected:
            return
        self._expected = -1
        if self.hold is not None:
            self.hold.release()

    def _send(self, ask: SnapshotAsk, part: SnapshotPart) -> None:
        payload = encode(part)
        self._sent = (ask, payload)
        self._pub.put(payload)

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
