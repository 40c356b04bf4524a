"""The page's buttons as bus messages: the monitor reaches the line only the way any other client can."""

from __future__ import annotations

import math

import zenoh

from fleet.bus.codec import encode
from fleet.bus.keys import Keys
from fleet.bus.messages import EStop, RespawnRequest, SimControl

SPEED_RANGE = (0.01, 100.0)


class LineControls:
    """Publishers for e-stop, pause/resume, speed factor, snapshots and respawn requests; `close()` undeclares
    them."""

    def __init__(self, session: zenoh.Session, keys: Keys, source: str = "monitor") -> None:
        self.source = source
        self._estop = session.declare_publisher(keys.estop)
        self._control = session.declare_publisher(keys.control)
        self._respawn = session.declare_publisher(keys.respawn)
        self.sent: list[str] = []  # what was asked, in order (shown on the page, handy in tests)

    def close(self) -> None:
        for pub in (self._estop, self._control, self._respawn):
            pub.undeclare()

    def emergency_stop(self, engaged: bool = True) -> None:
        """Hold every arm within one tick (`engaged`), or release the hold."""
        self._estop.put(encode(EStop(engaged, self.source)))
        self.sent.append("estop" if engaged else "release")

    def pause(self, paused: bool = True) -> None:
        self._control.put(encode(SimControl(self.source, paused=paused)))
        self.sent.append("pause" if paused else "resume")

    def set_speed(self, factor: float) -> None:
        """The realtime speed factor (x real time); a lockstep sim runs as fast as it can and ignores it."""
        lo, hi = SPEED_RANGE
        if not (math.isfinite(factor) and lo <= factor <= hi):
            raise ValueError(f"speed factor {factor} outside {lo}..{hi}")
        self._control.put(encode(SimControl(self.source, speed=float(factor))))
        self.sent.append(f"speed {factor:g}")

    def snapshot(self) -> None:
        """Ask the sim for a snapshot of the whole run at its next tick boundary (into the run's `--out` folder)."""
        self._control.put(encode(SimControl(self.source, snapshot=True)))
        self.sent.append("snapshot")

    def respawn(self, arm: str) -> None:
        """Ask the launcher to start `arm`'s controller again (it refuses if that controller is alive and heard)."""
        self._respawn.put(encode(RespawnRequest(arm, self.source)))
        self.sent.append(f"respawn {arm}")
