"""Acting on a running line at moments of its sim time, however fast it runs: a lockstep line can cover its
whole length between two of the launcher's progress reports (every 0.5 s of wall time), so a test that waited
for one inside a window of sim time could find none."""

from __future__ import annotations

import threading

import zenoh

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState
from fleet.bus.session import Inbox


class SimTimeTrigger:
    """Calls `act()` once the line's sim time (its arms' states, heard on `session`) passes each of `at_s`, from a
    thread of its own that wakes on every state; `times` counts the calls. Use in a `with` block around the run: an
    exception `act` raised is raised again when the block ends (a thread's own would go unseen)."""

    def __init__(self, session: zenoh.Session, keys: Keys, at_s: list[float], act) -> None:
        self.at_s, self.act, self.times = sorted(at_s), act, 0
        self.raised: BaseException | None = None
        self.inbox, self.decoder = Inbox(), Decoder(ArmState, DropCounter())
        self.sub = session.declare_subscriber(keys.all_arms("state"), self.inbox)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._watch, daemon=True)

    def __enter__(self) -> SimTimeTrigger:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.thread.join(5)
        self.sub.undeclare()
        if self.raised is not None and exc[0] is None:
            raise AssertionError(f"act raised at a moment of sim time: {self.raised!r}") from self.raised

    def _watch(self) -> None:
        try:
            self._watch_states()
        except Exception as exc:  # noqa: BLE001 - handed to the test when its block ends
            self.raised = exc

    def _watch_states(self) -> None:
        pending = list(self.at_s)
        while pending and not self.stop.is_set():
            for key, payload in self.inbox.drain():
                state = self.decoder.decode(key, payload)
                while state is not None and pending and state.sim_time_s >= pending[0]:
                    pending.pop(0)
                    self.act()
                    self.times += 1
            self.inbox.wait(0.05)
