"""The perception node's work, apart from its process: camera images off the bus paired into RGB-D frames, parts
detected and tracked (`perception/`), one `PartDetections` message a frame; with the line's events, the line's parts
as seen (`LineSight`), one `PartsState` a frame tick; what it took, refused and cost.

A frame waits until every camera due at its tick is in and the line events published before it have come (they
travel on another key), so that a lockstep line sees the same parts every run."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.messages import CameraImage, LineEvent, PartDetections, PartsState
from fleet.nodes.line_sight import LineSight
from fleet.nodes.rgbd_pairs import RGBDPairs
from fleet.sim.cameras.part_looks import part_looks
from perception.detect import detect_parts
from perception.rgbd import RGBDFrame
from perception.seen_ticks import frame_due
from perception.tracks import PartTracks
from scenes.schema import Scene

TOP_BAND_SPARE_M = 0.02  # a part on the belt has its top face at most its height and this above the belt's surface
FRAME_WAIT_S = 0.5  # a frame waits at most this long (wall) for its other cameras and its events


def belt_velocity_at(scene: Scene) -> Callable[[np.ndarray], np.ndarray]:
    """The surface velocity under a world point: the conveyor's over its belt (a part lying on it rides it; one
    lifted above it, in a claw, does not), else 0."""
    belt = scene.conveyor
    if belt is None or belt.speed_m_per_s == 0.0:
        return lambda point: np.zeros(3)
    c, s = math.cos(belt.pose.yaw_rad), math.sin(belt.pose.yaw_rad)
    x0, y0, z0 = belt.pose.xyz
    velocity = np.asarray(belt.direction) * belt.speed_m_per_s
    band_m = max((p.size_m[2] for f in scene.feeders for p in f.parts), default=0.0) + TOP_BAND_SPARE_M

    def at(point: np.ndarray) -> np.ndarray:
        dx, dy = point[0] - x0, point[1] - y0
        along, across = c * dx + s * dy, -s * dx + c * dy
        on = 0.0 <= along <= belt.length_m and abs(across) <= belt.width_m / 2 and point[2] <= z0 + band_m
        return velocity if on else np.zeros(3)

    return at


def rests_at(scene: Scene) -> Callable[[np.ndarray], bool]:
    """Whether a part whose top face is at a world point can be lying on something: at most two part heights above
    the highest surface of the line (the belt, a station's top); higher, it is in the air, in a claw."""
    tallest_m = max((p.size_m[2] for f in scene.feeders for p in f.parts), default=0.0)
    tops = [s.pose.xyz[2] + s.size_m[2] for s in scene.stations]
    if scene.conveyor is not None:
        tops.append(scene.conveyor.pose.xyz[2])
    ceiling_m = max(tops, default=0.0) + 2 * tallest_m + TOP_BAND_SPARE_M
    return lambda point: point[2] <= ceiling_m


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
        self.looks, kinds = part_looks(scene)
        self.cameras, self.publish, self.publish_parts = cameras, publish, publish_parts
        self.rates_hz = {c.name: c.rate_hz for c in scene.cameras if c.name in cameras}
        self.tracks = {name: PartTracks(belt_velocity_at(scene), rests_at=rests_at(scene)) for name in cameras}
        self.sight = LineSight(scene, self.looks, kinds, belt_velocity_at(scene))
        self.drops = DropCounter()
        self.pairs = RGBDPairs(cameras, self.drops)
        self._event_decoder = Decoder(LineEvent, self.drops)
        self._waiting: dict[int, dict[str, tuple[CameraImage, RGBDFrame | None]]] = {}  # by tick: frames not seen
        self._since: dict[int, float] = {}  # by tick: when its first frame came in (wall)
        self.frames = self.detections = 0
        self.frames_on_deadline = 0
        self.detect_s: list[float] = []

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
            self.sight.apply_events(tick)
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
        start = time.perf_counter()
        believed = self.tracks[rgb.camera].update(detect_parts(frame, self.looks), rgb.sim_time_s)
        self.sight.update(rgb.camera, believed, rgb.sim_time_s)
        self.detect_s.append(time.perf_counter() - start)
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
        ms = np.asarray(self.detect_s) * 1000.0
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
