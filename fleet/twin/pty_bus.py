"""An STS servo line on a pseudo-terminal: a driver opens `PtyServoBus.port` as it would a USB serial adapter
(`/dev/ttyACM0`) and the servos of a `ServoLine` answer its packets. The terminal is raw (no echo, no line
discipline), so every byte goes through as on the wire; the baud rate a driver sets is taken and ignored."""

from __future__ import annotations

import os
import select
import threading
import tty
from collections.abc import Callable

from robots.feetech.packets import PacketReader
from robots.feetech.servos import ServoLine

IDLE_S = 0.05  # no byte for this long: the bus is idle (`on_idle`)


class PtyServoBus:
    """Serves `line` on a pseudo-terminal from a thread of its own, from `with` on; `port` is the path a driver
    opens. `after_packets` is called once the packets that came together were answered (a sync write of every
    goal: its joints sent on together). What came that was not a packet is counted (`reader.corrupt`,
    `reader.skipped_bytes`)."""

    def __init__(
        self,
        line: ServoLine,
        after_packets: Callable[[], None] = lambda: None,
        on_idle: Callable[[], None] = lambda: None,
    ) -> None:
        self.line, self.after_packets, self.on_idle = line, after_packets, on_idle
        self.reader = PacketReader()
        self.packets = 0
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.port = os.ttyname(self._slave)
        self._stop_r, self._stop_w = os.pipe()
        self._thread = threading.Thread(target=self._serve, name="servo-bus", daemon=True)

    def __enter__(self) -> PtyServoBus:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        if self._thread.is_alive():
            os.write(self._stop_w, b"x")
            self._thread.join(5.0)
        for fd in (self._master, self._slave, self._stop_r, self._stop_w):
            try:
                os.close(fd)
            except OSError:
                pass

    def _serve(self) -> None:
        while True:
            ready, _, _ = select.select([self._master, self._stop_r], [], [], IDLE_S)
            if self._stop_r in ready:
                return
            if not ready:
                self.on_idle()
                continue
            try:
                data = os.read(self._master, 4096)
            except OSError:  # the driver's side closed and nothing holds it open: nothing more to read
                return
            answers = b""
            for p in self.reader.feed(data):
                self.packets += 1
                answers += self.line.answer(p)
            if answers:  # first: a driver waits for them (tens of ms), the line for nothing
                os.write(self._master, answers)
            self.after_packets()
