"""The STS servos' packets (Feetech's SCS protocol 0, as `scservo_sdk` speaks it): an instruction is
`FF FF id length instruction params... checksum`, a servo's status `FF FF id length error params... checksum`;
length counts the bytes after it, the checksum is the inverted low byte of the sum from id on.

`PacketReader` cuts a byte stream into packets the way a servo listens: it waits for the two header bytes, and a
packet whose checksum is wrong is dropped and counted (a servo does not answer it)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

BROADCAST_ID = 0xFE
HEADER = b"\xff\xff"
MAX_LENGTH = 250  # a packet's length byte: no instruction the servos know needs more


class Instruction(IntEnum):
    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83


class ErrorBit(IntEnum):
    """The bits of a status packet's error byte."""

    VOLTAGE = 0x01
    ANGLE = 0x02
    OVERHEAT = 0x04
    OVER_CURRENT = 0x08
    OVERLOAD = 0x20


def checksum(body: bytes) -> int:
    """The checksum of a packet's bytes from its id to its last parameter."""
    return ~sum(body) & 0xFF


def packet(servo_id: int, code: int, params: bytes = b"") -> bytes:
    """An instruction (`code` an `Instruction`) or a status packet (`code` its error byte)."""
    body = bytes([servo_id, len(params) + 2, code]) + params
    return HEADER + body + bytes([checksum(body)])


@dataclass(frozen=True)
class Packet:
    """One packet off the line: to (or from) `servo_id`, its instruction (or error byte) and parameters."""

    servo_id: int
    code: int
    params: bytes


class PacketReader:
    """Bytes in (`feed`), whole packets out, in order. A packet with a wrong checksum, or a length no packet has,
    is dropped and counted in `corrupt`; bytes before a header are skipped and counted in `skipped_bytes`."""

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.corrupt = 0
        self.skipped_bytes = 0

    def feed(self, data: bytes) -> list[Packet]:
        self._buffer.extend(data)
        out = []
        while (packet := self._next()) is not None:
            out.append(packet)
        return out

    def _next(self) -> Packet | None:
        while True:
            start = self._buffer.find(HEADER)
            if start < 0:  # keep a last 0xFF: it may be the first half of a header
                keep = 1 if self._buffer.endswith(b"\xff") else 0
                self.skipped_bytes += len(self._buffer) - keep
                del self._buffer[: len(self._buffer) - keep]
                return None
            self.skipped_bytes += start
            del self._buffer[:start]
            if len(self._buffer) < 4:
                return None
            servo_id, length = self._buffer[2], self._buffer[3]
            if servo_id == 0xFF or not 2 <= length <= MAX_LENGTH:  # a third 0xFF, or no packet's length
                self.skipped_bytes += 1
                del self._buffer[:1]
                continue
            end = 4 + length
            if len(self._buffer) < end:
                return None
            body, check = bytes(self._buffer[2 : end - 1]), self._buffer[end - 1]
            del self._buffer[:end]
            if checksum(body) != check:
                self.corrupt += 1
                continue
            return Packet(servo_id, body[2], body[3:])
