"""The line's cameras on the monitor's page: an image panel for each camera whose colour images the line puts on the
bus (made at its first frame), showing its newest frame at most `CAP_HZ` times a wall second (a lockstep line
renders faster than a page need redraw)."""

from __future__ import annotations

import time

import numpy as np
import viser
import zenoh
from zenoh.handlers import RingChannel

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.images import decode_image
from fleet.bus.keys import Keys
from fleet.bus.messages import CameraImage
from scenes.schema import Scene

CAP_HZ = 2.0


class CameraPanels:
    """Image panels fed from the cameras' colour images on the bus; `show()` each monitor frame, `close()` at the
    end. A camera the line does not render gets no panel."""

    def __init__(self, server: viser.ViserServer, session: zenoh.Session, keys: Keys, scene: Scene) -> None:
        self.server = server
        self.drops = DropCounter()
        self.shown = 0
        self._decoder = Decoder(CameraImage, self.drops)
        self._folder = None
        self._panels: dict[str, viser.GuiImageHandle] = {}
        self._last: dict[str, float] = {}
        self._subs = {
            c.name: (keys.camera(c.name, "rgb"), session.declare_subscriber(keys.camera(c.name, "rgb"), RingChannel(1)))
            for c in scene.cameras
            if "rgb" in c.images
        }

    def _panel(self, camera: str, image: np.ndarray) -> None:
        """The camera's panel showing `image`, made at its first."""
        if camera in self._panels:
            self._panels[camera].image = image
            return
        if self._folder is None:
            self._folder = self.server.gui.add_folder("Cameras", expand_by_default=True)
        with self._folder:
            self._panels[camera] = self.server.gui.add_image(image, label=camera, format="jpeg")

    def show(self) -> None:
        """The newest frame of each camera, where one came and its panel may redraw."""
        now = time.monotonic()
        for camera, (key, sub) in self._subs.items():
            if now - self._last.get(camera, -1e9) < 1.0 / CAP_HZ:
                continue
            sample = sub.try_recv()
            if sample is None:
                continue
            message = self._decoder.decode(key, sample.payload.to_bytes())
            if message is None:
                continue
            try:
                image = decode_image("rgb", message.data, message.encoding, message.width_px, message.height_px)
            except ValueError as exc:
                self.drops.drop(key, str(exc))
                continue
            self._panel(camera, image)
            self._last[camera] = now
            self.shown += 1

    def close(self) -> None:
        for _, sub in self._subs.values():
            sub.undeclare()
        self._subs = {}
