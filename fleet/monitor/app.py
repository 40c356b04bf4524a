"""The monitor: a Viser server drawing one line, fed from the bus at `rate_hz`, with controls that publish on it."""

from __future__ import annotations

import sys
import time

import viser
import zenoh

from fleet.bus.keys import Keys
from fleet.common.processes import StopFlag
from fleet.monitor.camera_panels import CameraPanels
from fleet.monitor.cell_view import CellView
from fleet.monitor.controls import LineControls
from fleet.monitor.feed import LiveFeed
from fleet.monitor.options import DEFAULT_HOST, DEFAULT_PORT, DEFAULT_RATE_HZ
from fleet.monitor.panel import Panel
from scenes.schema import Scene


class Monitor:
    """Use in a `with` block: the Viser server, the bus subscribers and publishers are released on leaving."""

    def __init__(
        self, session: zenoh.Session, keys: Keys, scene: Scene, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT
    ) -> None:
        self.host = host
        self.server = viser.ViserServer(host=host, port=port, label=f"clawfleet · {scene.name}", verbose=False)
        try:
            self.feed = LiveFeed(session, keys, [a.name for a in scene.arms])
            self.controls = LineControls(session, keys)
            self.view = CellView(self.server, scene)
            self.panel = Panel(self.server, scene, self.controls)
            self.cameras = CameraPanels(self.server, session, keys, scene)
        except BaseException:
            self.server.stop()
            raise
        self.frames = 0
        self.extras: list = [self.cameras]  # panels to refresh each frame (with `show()`): cameras, replay controls
        self.most_pages_open = 0
        self.started_at: float | None = None

    @property
    def frames_per_s(self) -> float:
        """Redraws per wall second since `run` began."""
        if self.started_at is None:
            return 0.0
        return self.frames / max(time.monotonic() - self.started_at, 1e-9)

    @property
    def port(self) -> int:
        return self.server.get_port()

    @property
    def url(self) -> str:
        return f"http://{self.host}:{self.port}"

    def __enter__(self) -> Monitor:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        self.cameras.close()
        self.feed.close()
        self.controls.close()
        self.server.stop()

    def frame(self) -> None:
        """Redraw from everything heard since the last frame."""
        snap = self.feed.take()
        with self.server.atomic():
            self.view.show(snap)
            self.panel.show(snap)
            for extra in self.extras:
                extra.show()
        self.frames += 1
        if self.frames % 30 == 0:
            self.most_pages_open = max(self.most_pages_open, len(self.server.get_clients()))

    def run(self, stop: StopFlag, rate_hz: float = DEFAULT_RATE_HZ) -> None:
        """Redraw at `rate_hz` on a fixed schedule (a late frame is not made up for) until `stop`."""
        period = 1.0 / rate_hz
        due = self.started_at = time.monotonic()
        while not stop.should_stop():
            self.frame()
            due = max(due + period, time.monotonic())
            time.sleep(max(0.0, due - time.monotonic()))


def print_url(monitor: Monitor, requested_port: int) -> None:
    if requested_port not in (0, monitor.port):
        print(f"monitor: port {requested_port} is taken, serving on {monitor.port}", file=sys.stderr)
    print(f"monitor: {monitor.url}", file=sys.stderr, flush=True)
