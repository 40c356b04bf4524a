"""One rosbridge client connection: what it subscribed to (with rosbridge's `throttle_rate` and `queue_length`)
and its outgoing queue, written to its socket by one task; a client that does not read loses its oldest
messages, never the line's time."""

from __future__ import annotations

import asyncio
import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field

MAX_QUEUED = 1000  # messages waiting for a slow client before its oldest are dropped


COMPRESSIONS = ("none", "cbor", "cbor-raw")  # rosbridge's, less png: JSON text, CBOR, CBOR around the CDR bytes


@dataclass
class Subscription:
    ids: set[str] = field(default_factory=set)  # a client may subscribe to a topic more than once (ids)
    throttle_s: float = 0.0
    queue_length: int = 0
    last_sent: float = -1e9
    compression: str = "none"  # one of `COMPRESSIONS`: how its messages are sent


class Client:
    """A connected client's subscriptions and outgoing queue."""

    def __init__(self, websocket, number: int) -> None:
        self.websocket, self.number = websocket, number
        self.subscriptions: dict[str, Subscription] = {}
        self.queue: asyncio.Queue[str | bytes] = asyncio.Queue()
        self.dropped = 0
        self.sent = 0
        self.authenticated = False
        self.peer_ip = str(websocket.remote_address[0]) if websocket.remote_address else ""
        self.local_ip = str(websocket.local_address[0]) if websocket.local_address else ""

    def send(self, message: dict) -> None:
        self.send_text(json.dumps(message, allow_nan=False))

    def send_text(self, text: str | bytes) -> None:
        if self.queue.qsize() >= MAX_QUEUED:
            self.queue.get_nowait()
            self.dropped += 1
        self.queue.put_nowait(text)

    def status(self, level: str, msg: str, op_id: object = None) -> None:
        """rosbridge's `status` message: how the server tells a client its request failed."""
        out = {"op": "status", "level": level, "msg": msg}
        if op_id is not None:
            out["id"] = op_id
        self.send(out)

    def offer(self, topic: str, encoded: Callable[[str], str | bytes]) -> None:
        """A published message of `topic`, as rosbridge's `publish` in the compression its subscription asked for
        (`encoded(compression)`: JSON text, or CBOR bytes sent as a binary frame); sent unless throttled."""
        sub = self.subscriptions.get(topic)
        if sub is None:
            return
        now = time.monotonic()
        if sub.throttle_s and now - sub.last_sent < sub.throttle_s:
            return
        sub.last_sent = now
        self.send_text(encoded(sub.compression))

    async def pump(self) -> None:
        """Write the queue to the socket until the connection ends."""
        while True:
            text = await self.queue.get()
            await self.websocket.send(text)
            self.sent += 1
