"""The bus spool: what a run's bus carried, as the sim's own session heard it, appended to a file that the recorder
turns into MCAP (`fleet run --record`).

The sim is the run's router, so a subscriber on its own session hears every message of the run, its own and
those it routes between the others, without one more link to send them on: a recorder tapping the bus as a
client cost a lockstep run some 10% of its wall time in Zenoh alone (`docs/benchmarks.md`), the spool about
nothing. The file is a header (run id, scene) then one frame per message, each length-prefixed msgpack, and an
end mark once the sim stops: a reader follows it while it grows and knows when it is whole.
"""

from __future__ import annotations

import struct
import time
from pathlib import Path
from typing import IO

import msgspec

from fleet.bus.session import Tap

SPOOL_VERSION = 1
FLUSH_EVERY_S = 0.1  # a reader following a realtime line sees what was heard this long ago at most
_LENGTH = struct.Struct("<I")
_END = b""  # the frame of length 0: the sim stopped, nothing follows


class SpoolHeader(msgspec.Struct, frozen=True):
    """The spool's first frame: what the recorder would otherwise ask the sim over the bus."""

    version: int
    run_id: str
    scene_json: str


class SpoolError(ValueError):
    """A spool that cannot be read (not one, another version, cut inside its header); one line for the user."""


class SpoolWriter:
    """Appends heard messages to the spool file; `close()` writes the end mark."""

    def __init__(self, path: str | Path, run_id: str, scene_json: str) -> None:
        self.path = Path(path)
        self._file: IO[bytes] = open(self.path, "wb")
        self._encode = msgspec.msgpack.Encoder().encode
        self._flushed_at = time.monotonic()
        self.messages = 0
        self._frame(self._encode(SpoolHeader(SPOOL_VERSION, run_id, scene_json)))
        self._file.flush()

    def _frame(self, body: bytes) -> None:
        self._file.write(_LENGTH.pack(len(body)))
        self._file.write(body)

    def write(self, batch: list[tuple[str, bytes]]) -> None:
        """Messages in the order heard; flushed to the file at most `FLUSH_EVERY_S` after."""
        for key, payload in batch:
            self._frame(self._encode((key, payload)))
        self.messages += len(batch)
        if time.monotonic() - self._flushed_at >= FLUSH_EVERY_S:
            self._file.flush()
            self._flushed_at = time.monotonic()

    def close(self) -> None:
        if not self._file.closed:
            self._frame(_END)
            self._file.close()


class BusSpool:
    """A tap on the sim's own session spooled to a file: `pump()` between ticks, `close()` at the end."""

    def __init__(self, session, keys: list[str], path: str | Path, run_id: str, scene_json: str) -> None:
        self.tap = Tap(session, keys)
        self.writer = SpoolWriter(path, run_id, scene_json)

    def pump(self) -> None:
        """What was heard since the last pump, appended (a few microseconds a message; no Python per message
        on Zenoh's own threads: the tap queues inside Zenoh)."""
        batch = self.tap.drain()
        if batch:
            self.writer.write(batch)

    def close(self) -> None:
        try:
            self.pump()
        finally:
            self.tap.close()
            self.writer.close()


class SpoolReader:
    """Follows a spool file while it grows: `drain()` the messages appended since, `ended` once the end mark is read."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self._file: IO[bytes] | None = None
        self._buffer = bytearray()
        self._decode_header = msgspec.msgpack.Decoder(SpoolHeader).decode
        self._decode = msgspec.msgpack.Decoder(tuple[str, bytes]).decode
        self.header: SpoolHeader | None = None
        self.ended = False
        self._pending: list[bytes] = []  # frames read with the header

    def _read_more(self) -> None:
        if self._file is None:
            if not self.path.exists():
                return
            self._file = open(self.path, "rb")
        self._buffer += self._file.read()

    def _frames(self) -> list[bytes]:
        """The whole frames in the buffer (a frame still being written stays for the next read)."""
        frames, at, buffer = [], 0, self._buffer
        while len(buffer) - at >= _LENGTH.size:
            (length,) = _LENGTH.unpack_from(buffer, at)
            if len(buffer) - at - _LENGTH.size < length:
                break
            frames.append(bytes(buffer[at + _LENGTH.size : at + _LENGTH.size + length]))
            at += _LENGTH.size + length
        del buffer[:at]
        return frames

    def wait_for_header(self, timeout_s: float, give_up=lambda: False) -> SpoolHeader | None:
        """The header, once the sim wrote it (None after `timeout_s`, or once `give_up()`)."""
        deadline = time.monotonic() + timeout_s
        while self.header is None:
            self._read_more()
            frames = self._frames()
            if frames:
                try:
                    self.header = self._decode_header(frames[0])
                except msgspec.DecodeError:
                    raise SpoolError(f"{self.path}: not a bus spool") from None
                if self.header.version != SPOOL_VERSION:
                    raise SpoolError(
                        f"{self.path}: spool version {self.header.version}, this reader reads {SPOOL_VERSION}"
                    )
                self._pending = frames[1:]
                break
            if time.monotonic() >= deadline or give_up():
                return None
            time.sleep(0.02)
        return self.header

    def drain(self) -> list[tuple[str, bytes]]:
        """(key, payload) of every message appended since the last drain, in the order the sim heard them."""
        if self.header is None or self.ended:
            return []
        self._read_more()
        frames, self._pending = [*self._pending, *self._frames()], []
        out = []
        for frame in frames:
            if frame == _END:
                self.ended = True
                break
            out.append(self._decode(frame))
        return out

    def close(self) -> None:
        if self._file is not None:
            self._file.close()
