"""Asking a queryable of the run until it answers: the one loop behind every fetch (the scene, the event log)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

import zenoh

T = TypeVar("T")


def first_answer(
    session: zenoh.Session, key: str, take: Callable[[bytes], T | None], timeout_s: float, per_query_s: float = 1.0
) -> T | None:
    """The first reply on `key` that `take` turns into something (None: not usable, the next one is taken),
    asked again until `timeout_s` passes; None if no usable reply came in time."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        for reply in session.get(key, timeout=min(per_query_s, max(deadline - time.monotonic(), 0.1))):
            if reply.ok is not None:
                answer = take(reply.ok.payload.to_bytes())
                if answer is not None:
                    return answer
        time.sleep(0.1)
    return None
