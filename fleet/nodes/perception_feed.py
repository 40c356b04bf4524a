"""The perception node's work, apart from its process: camera images off the bus paired into RGB-D frames, parts
detected and tracked (`perception/`), one `PartDetections` message a frame; with the line's events, the line's parts
as seen (`fleet.sight`), one `PartsState` a frame tick; what it took, refused and cost.

A frame waits until every camera due at its tick is in and the line events published before it have come (they
travel on another key), so that a lockstep line sees the same parts every run."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.messages import CameraImage, LineEvent, PartDetections, PartsState
from fleet.nodes.rgbd_pairs import RGBDPairs
from fleet.sight.seer import Seer
from perception.rgbd import RGBDFrame
from perception.seen_ticks import frame_due
from scenes.schema import Scene

FRAME_WAIT_S = 0.5  # a frame waits at most this long (wall) for its other cameras and its events


class PerceptionFeed:
    """Takes `CameraImage` payloads of `scene`'s cameras and the line's events (`take`); once a frame's colour and
    depth are both in, it detects and tracks the parts and hands `publish` one `PartDetections`; once a tick's
    frames and events are all in (`ready`), `publish_parts` gets the line's parts as seen then. A payload that
    does not decode, or cannot be an image of that camera or an event of this line, is dropped and counted
    (`drops`)."""

    def __init__(
        self,
        scene: Scene,
        cameras: list[str],
        publish: Callable[[str, PartDetections], None],
        publish_parts: Callable[[PartsState], None] = lambda msg: None,
    ) -> None:
        self.scene = scene
        self.cameras, self.publish, self.publish_parts = cameras, publish, publish_parts
        self.rates_hz = {c.name: c.rate_hz for c in scene.cameras if c.name in cameras}
        self.seer = Seer(scene, cameras)
        self.sight = self.seer.sight
        self.drops = DropCounter()
        self.pairs = RGBDPairs(cameras, self.drops)
        self._event_decoder = Decoder(LineEvent, self.drops)
        self._waiting: dict[int, dict[str, tuple[CameraImage, RGBDFrame | None]]] = {}  # by tick: frames not seen
        self._since: dict[int, float] = {}  # by tick: when its first frame came in (wall)
        self.frames = self.detections = 0
        self.frames_on_deadline = 0

    def take(self, key: str, payload: bytes) -> None:
        if key.endswith("/world/events"):
            event = self._event_decoder.decode(key, payload)
            if event is not None:
                self.sight.event(key, event, self.drops)
            return
        paired = self.pairs.take(key, payload)
        if paired is not None:
            rgb, frame = paired
            self._waiting.setdefault(rgb.tick, {})[rgb.camera] = (rgb, frame)
            self._since.setdefault(rgb.tick, time.monotonic())

    def see(self, now_s: float | None = None) -> int:
        """See the frames whose ticks are ready, in tick order; how many ticks were seen. A tick is ready once every
        camera due then is in and the events its frames name have come, or `FRAME_WAIT_S` after its first frame."""
        now_s = time.monotonic() if now_s is None else now_s
        seen = 0
        for tick in sorted(self._waiting):
            frames = self._waiting[tick]
            due = [c for c in self.cameras if frame_due(tick, self.rates_hz[c], self.scene.control_hz)]
            events = max(rgb.events_published for rgb, _ in frames.values())
            complete = all(c in frames for c in due) and self.sight.events_seen >= events
            if not complete and now_s - self._since[tick] <= FRAME_WAIT_S:
                break  # later ticks wait behind it: frames are seen in order
            self.frames_on_deadline += not complete
            del self._waiting[tick], self._since[tick]
            self.sight.apply_events(tick, events)
            time_s = 0.0
            for camera in sorted(frames):
                rgb, frame = frames[camera]
                if frame is not None:  # a pair that could not be a frame was dropped and counted
                    self._frame(rgb, frame)
                time_s = rgb.sim_time_s
            self.publish_parts(self.sight.message(tick, time_s))
            seen += 1
        return seen

    def _frame(self, rgb: CameraImage, frame: RGBDFrame) -> None:
        believed = self.seer.frame(rgb.camera, frame)
        self.frames += 1
        self.detections += len(believed)
        self.publish(
            rgb.camera,
            PartDetections(
                rgb.camera,
                rgb.tick,
                rgb.sim_time_s,
                tuple(t.track_id for t in believed),
                tuple(t.kind for t in believed),
                tuple(float(v) for t in believed for v in t.top_centre_m),
                tuple(float(t.yaw_rad) for t in believed),
                tuple(float(t.confidence) for t in believed),
                tuple(float(t.seen_s) for t in believed),
            ),
        )

    def report(self) -> dict:
        """The node's figures for the run summary."""
        ms = np.asarray(self.seer.detect_s) * 1000.0
        return {
            "cameras": list(self.cameras),
            "frames": self.frames,
            "tracks_published": self.detections,
            "detect_ms_p50": round(float(np.percentile(ms, 50)), 2) if len(ms) else None,
            "detect_ms_p95": round(float(np.percentile(ms, 95)), 2) if len(ms) else None,
            "frames_on_deadline": self.frames_on_deadline,
            **self.sight.report(),
            "dropped_messages": self.drops.total,
            "refused_messages": self.drops.kinds(),
        }
