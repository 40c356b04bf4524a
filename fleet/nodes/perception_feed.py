"""The perception node's work, apart from its process: camera images off the bus paired into RGB-D frames, parts
detected and tracked (`perception/`), one `PartDetections` message a frame; what it took, refused and cost."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.images import decode_image
from fleet.bus.messages import CameraImage, PartDetections
from fleet.sim.cameras.part_looks import part_looks
from perception.detect import detect_parts
from perception.rgbd import RGBDFrame
from perception.tracks import PartTracks
from scenes.schema import Scene

BELT_TOP_BAND_M = 0.25  # a part on the belt has its top face at most this far above the belt's surface


def belt_velocity_at(scene: Scene) -> Callable[[np.ndarray], np.ndarray]:
    """The surface velocity under a world point: the conveyor's over its belt (a part on it rides it), else 0."""
    belt = scene.conveyor
    if belt is None or belt.speed_m_per_s == 0.0:
        return lambda point: np.zeros(3)
    c, s = math.cos(belt.pose.yaw_rad), math.sin(belt.pose.yaw_rad)
    x0, y0, z0 = belt.pose.xyz
    velocity = np.asarray(belt.direction) * belt.speed_m_per_s

    def at(point: np.ndarray) -> np.ndarray:
        dx, dy = point[0] - x0, point[1] - y0
        along, across = c * dx + s * dy, -s * dx + c * dy
        on = 0.0 <= along <= belt.length_m and abs(across) <= belt.width_m / 2 and point[2] <= z0 + BELT_TOP_BAND_M
        return velocity if on else np.zeros(3)

    return at


class PerceptionFeed:
    """Takes `CameraImage` payloads (`take`) of `scene`'s cameras; once a frame's colour and depth are both in, it
    detects and tracks the parts and hands `publish` one `PartDetections`. A payload that does not decode, or
    cannot be an image of that camera, is dropped and counted (`drops`)."""

    def __init__(self, scene: Scene, cameras: list[str], publish: Callable[[str, PartDetections], None]) -> None:
        self.looks, _ = part_looks(scene)
        self.cameras, self.publish = cameras, publish
        self.tracks = {name: PartTracks(belt_velocity_at(scene)) for name in cameras}
        self.drops = DropCounter()
        self._decoder = Decoder(CameraImage, self.drops)
        self._halves: dict[str, dict[str, CameraImage]] = {name: {} for name in cameras}
        self.frames = self.detections = 0
        self.detect_s: list[float] = []

    def take(self, key: str, payload: bytes) -> None:
        msg = self._decoder.decode(key, payload)
        if msg is None:
            return
        if (
            msg.camera not in self._halves
            or msg.kind not in ("rgb", "depth")
            or not key.endswith(f"/camera/{msg.camera}/{msg.kind}")
        ):
            self.drops.drop(key, "an image of another camera or kind than its key's, or of a camera not perceived")
            return
        halves = self._halves[msg.camera]
        if any(h.tick != msg.tick for h in halves.values()):
            halves.clear()  # a half whose other half never came: that frame is lost
        halves[msg.kind] = msg
        if len(halves) == 2:
            self._frame(halves.pop("rgb"), halves.pop("depth"))

    def _frame(self, rgb: CameraImage, depth: CameraImage) -> None:
        where = (rgb.sim_time_s, *rgb.intrinsics, *rgb.position_m, *rgb.quaternion_wxyz)
        if len(rgb.intrinsics) != 9 or len(rgb.position_m) != 3 or len(rgb.quaternion_wxyz) != 4:
            self.drops.drop(f"camera/{rgb.camera}", "a frame whose intrinsics or pose has the wrong length")
            return
        if not np.isfinite(where).all() or abs(np.linalg.norm(rgb.quaternion_wxyz) - 1.0) > 1e-3:
            self.drops.drop(f"camera/{rgb.camera}", "a frame with NaN or infinite values, or no rotation")
            return
        try:
            depth_m = decode_image("depth", depth.data, depth.encoding, depth.width_px, depth.height_px)
            frame = RGBDFrame(
                rgb.camera,
                rgb.sim_time_s,
                decode_image("rgb", rgb.data, rgb.encoding, rgb.width_px, rgb.height_px),
                np.where(np.isfinite(depth_m), depth_m, 0.0).astype(np.float32),  # no depth where it is not a number
                np.asarray(rgb.intrinsics, float).reshape(3, 3),
                np.asarray(rgb.position_m, float),
                np.asarray(rgb.quaternion_wxyz, float),
            )
        except ValueError as exc:
            self.drops.drop(f"camera/{rgb.camera}", f"an image that does not decode: {str(exc)[:80]}")
            return
        start = time.perf_counter()
        believed = self.tracks[rgb.camera].update(detect_parts(frame, self.looks), rgb.sim_time_s)
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
            "dropped_messages": self.drops.total,
            "refused_messages": self.drops.kinds(),
        }
