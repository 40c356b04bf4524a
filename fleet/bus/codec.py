"""Encoding and checked decoding of bus messages: a bad payload is dropped, counted and logged once.

MessagePack through msgspec: typed decoding into the dataclasses of
`fleet.bus.messages`, about a tenth of JSON's size for joint vectors, and a
decode error instead of a half-filled message.
"""

from __future__ import annotations

import logging
import re
from collections import Counter
from dataclasses import dataclass, field
from typing import Generic, TypeVar

import msgspec
import numpy as np

from fleet.bus.messages import PROTOCOL_VERSION

T = TypeVar("T")
log = logging.getLogger("clawfleet.bus")


def _numpy_hook(obj: object) -> object:
    """Encode numpy scalars and arrays as plain numbers and lists."""
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise NotImplementedError(f"cannot encode {type(obj).__name__} on the bus")


_ENCODER = msgspec.msgpack.Encoder(enc_hook=_numpy_hook)


def encode(message: object) -> bytes:
    """The wire bytes of a message dataclass."""
    return _ENCODER.encode(message)


@dataclass
class DropCounter:
    """Counts dropped payloads by key and reason; logs the first of each kind only."""

    counts: Counter = field(default_factory=Counter)

    def drop(self, key: str, reason: str) -> None:
        first = (key, reason) not in self.counts
        self.counts[(key, reason)] += 1
        if first:
            log.warning("dropped a message on %s: %s (further ones are counted, not logged)", key, reason)

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def state(self) -> list[tuple[str, str, int]]:
        """The counts as a run's snapshot keeps them: (key, reason, how many)."""
        return [(key, reason, n) for (key, reason), n in self.counts.items()]

    def restore(self, state: list[tuple[str, str, int]]) -> None:
        """The counts of `state` put back in place (decoders counting into this counter keep doing so)."""
        self.counts = Counter({(key, reason): n for key, reason, n in state})

    def kinds(self) -> dict[str, int]:
        """The counts by kind: the key's leaf (`assign`, `status`, `step`, ...) and the reason with its numbers
        and quoted names blanked, so one kind of lie is one entry however often it came."""
        out: Counter = Counter()
        for (key, reason), n in self.counts.items():
            out[f"{key.rsplit('/', 1)[-1]}: {_KIND_BLANKS.sub('_', reason)[:100]}"] += n
        return dict(sorted(out.items()))


_KIND_BLANKS = re.compile(r"'[^']*'|-?\d+(\.\d+)?(e[-+]?\d+)?")


class Decoder(Generic[T]):
    """Decodes one message type; `decode` returns None (and counts the drop) for anything malformed."""

    def __init__(self, message_type: type[T], drops: DropCounter) -> None:
        self.message_type = message_type
        self.type_name = getattr(message_type, "__name__", None) or " | ".join(
            t.__name__ for t in message_type.__args__
        )
        self._decoder = msgspec.msgpack.Decoder(message_type)
        self.drops = drops

    def decode(self, key: str, payload: bytes) -> T | None:
        try:
            message = self._decoder.decode(payload)
        except (
            msgspec.MsgspecError,
            UnicodeDecodeError,
            ValueError,
            OverflowError,
        ) as exc:  # bad UTF-8 is not a DecodeError
            self.drops.drop(key, f"malformed {self.type_name}: {str(exc)[:120]}")
            return None
        if message.version != PROTOCOL_VERSION:  # type: ignore[attr-defined]
            self.drops.drop(key, f"protocol version {message.version}, expected {PROTOCOL_VERSION}")  # type: ignore[attr-defined]
            return None
        return message
