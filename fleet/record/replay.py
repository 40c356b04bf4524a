"""Playing a recording back onto the bus, paced by its sim time stamps: subscribers (a monitor, a user's
script) see the line as if it ran now.

Every raw bus message is published again on its key (under the target run id), at its recorded sim time
divided by the speed; the sim's `LineView` frames go out on `world/view` as well, which is what monitors
draw. The scene is answered on `world/scene` as the sim would. `world/control` works as on a live line:
pause, resume and speed act on the playback. A jump (`seek`) publishes the newest message of each key up
to that time, so a subscriber sees the line as it was then.
"""

from __future__ import annotations

import bisect
import threading
import time
from dataclasses import dataclass

import zenoh

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import SimControl
from fleet.bus.scene_query import serve_scene
from fleet.bus.session import Inbox
from fleet.common.processes import StopFlag
from fleet.record.mcap_file import RawMessage, Recording

STEP_S = 0.01  # wall seconds between publishing rounds


@dataclass
class PlaybackClock:
    """Where playback stands (sim seconds), whether it plays, and how fast against the wall clock."""

    start_s: float
    end_s: float
    position_s: float
    speed: float = 1.0
    playing: bool = True

    def advance(self, wall_s: float) -> float:
        """Move on by `wall_s` of wall time (if playing); pauses at the end. The new position."""
        if self.playing:
            self.position_s = min(self.end_s, self.position_s + wall_s * self.speed)
            if self.position_s >= self.end_s:
                self.playing = False
        return self.position_s

    def clamp(self, t_s: float) -> float:
        return min(self.end_s, max(self.start_s, t_s))


class Player:
    """Publishes a recording's raw bus messages on `keys` (use in a `with` block: its publishers are undeclared)."""

    def __init__(
        self, recording: Recording, session: zenoh.Session, keys: Keys, from_s: float | None = None, speed: float = 1.0
    ) -> None:
        self.recording, self.session, self.keys = recording, session, keys
        source = Keys(recording.run_id).prefix
        self.messages: list[RawMessage] = [
            RawMessage(keys.prefix + m.key[len(source) :], m.payload, m.stamp_ns)
            for m in recording.raw_messages()
            if m.key.startswith(source)
        ]
        self.stamps_s = [m.stamp_ns / 1e9 for m in self.messages]
        start, end = recording.start_ns / 1e9, recording.end_ns / 1e9
        self.clock = PlaybackClock(start, end, start if from_s is None else min(end, max(start, from_s)), speed)
        self.next_index = bisect.bisect_left(self.stamps_s, self.clock.position_s)
        self.published = 0
        self._lock = threading.Lock()
        self._frame, self._view = keys.frame, keys.view
        self._pubs: dict[str, zenoh.Publisher] = {}
        self._scene = serve_scene(session, keys, recording.scene_json)
        self._control_inbox = Inbox()
        self._control_sub = session.declare_subscriber(keys.control, self._control_inbox)
        self._control_decoder = Decoder(SimControl, DropCounter())

    def __enter__(self) -> Player:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        for pub in self._pubs.values():
            pub.undeclare()
        self._pubs.clear()
        self._scene.undeclare()
        self._control_sub.undeclare()

    def _publish(self, message: RawMessage) -> None:
        keys = [message.key, self._view] if message.key == self._frame else [message.key]
        for key in keys:
            if key not in self._pubs:
                self._pubs[key] = self.session.declare_publisher(key)
            self._pubs[key].put(message.payload)
            self.published += 1

    def publish_until(self, t_s: float) -> int:
        """Publish every message stamped up to `t_s` not published yet; how many."""
        with self._lock:
            end = bisect.bisect_right(self.stamps_s, t_s)
            for message in self.messages[self.next_index : end]:
                self._publish(message)
            count, self.next_index = max(0, end - self.next_index), max(self.next_index, end)
            return count

    def seek(self, t_s: float) -> None:
        """Jump to `t_s`: the newest message of each key up to then goes out, playback goes on from there."""
        with self._lock:
            t_s = self.clock.clamp(t_s)
            end = bisect.bisect_right(self.stamps_s, t_s)
            newest: dict[str, RawMessage] = {}
            for message in self.messages[:end]:
                newest[message.key] = message
            for message in sorted(newest.values(), key=lambda m: m.stamp_ns):
                self._publish(message)
            self.clock.position_s, self.next_index = t_s, end

    def control(self, playing: bool | None = None, speed: float | None = None) -> None:
        """Play or pause (at the end, playing starts again from the start), and the speed (0.01 to 100)."""
        with self._lock:
            if speed is not None and 0.01 <= speed <= 100:
                self.clock.speed = speed
        if playing and self.clock.position_s >= self.clock.end_s:
            self.seek(self.clock.start_s)
        if playing is not None:
            with self._lock:
                self.clock.playing = playing

    def _take_controls(self) -> None:
        for key, payload in self._control_inbox.drain():
            msg = self._control_decoder.decode(key, payload)
            if msg is None:
                continue
            with self._lock:
                if msg.paused is not None:
                    self.clock.playing = not msg.paused and self.clock.position_s < self.clock.end_s
                if msg.speed is not None and 0.01 <= msg.speed <= 100:
                    self.clock.speed = msg.speed

    def run(self, stop: StopFlag, until_end: bool = True) -> None:
        """Play on the wall clock until `stop` (or, with `until_end`, until the recording's end)."""
        if self.clock.position_s > self.clock.start_s:  # starting part way: the line as it was then, first
            self.seek(self.clock.position_s)
        last = time.monotonic()
        while not stop.should_stop():
            self._take_controls()
            now = time.monotonic()
            with self._lock:
                position = self.clock.advance(now - last)
            last = now
            self.publish_until(position)
            if until_end and position >= self.clock.end_s:
                return
            time.sleep(STEP_S)
