"""Camera images off the bus made into RGB-D frames: a camera's colour and depth of one tick paired, checked and
decoded (`perception.rgbd.RGBDFrame`). Anything that cannot be a frame of the cameras asked for is dropped and
counted."""

from __future__ import annotations

import numpy as np

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.images import decode_image
from fleet.bus.messages import CameraImage
from perception.rgbd import RGBDFrame

HALF_TICKS_KEPT = 4  # a camera's ticks whose other half may still come (colour and depth travel on two keys)


class RGBDPairs:
    """Pairs `cameras`' colour and depth images by tick (`take`). The halves travel on two keys, so one of a later
    frame may come first: a half waits until its camera has `HALF_TICKS_KEPT` newer ticks, then is forgotten."""

    def __init__(self, cameras: list[str], drops: DropCounter) -> None:
        self.drops = drops
        self._decoder = Decoder(CameraImage, drops)
        self._halves: dict[str, dict[int, dict[str, CameraImage]]] = {name: {} for name in cameras}
        self.heard = 0  # images taken (whatever became of them)

    def take(self, key: str, payload: bytes) -> tuple[CameraImage, RGBDFrame | None] | None:
        """A payload on a camera key: None until a frame's both halves are in, then its colour image's message
        and the frame (None: the pair cannot be a frame, dropped and counted)."""
        self.heard += 1
        msg = self._decoder.decode(key, payload)
        if msg is None:
            return None
        if (
            msg.camera not in self._halves
            or msg.kind not in ("rgb", "depth")
            or not key.endswith(f"/camera/{msg.camera}/{msg.kind}")
        ):
            self.drops.drop(key, "an image of another camera or kind than its key's, or of a camera not perceived")
            return None
        by_tick = self._halves[msg.camera]
        halves = by_tick.setdefault(msg.tick, {})
        halves[msg.kind] = msg
        for old in sorted(by_tick)[:-HALF_TICKS_KEPT]:
            del by_tick[old]  # a half whose other half never came: that frame is lost
        if len(halves) < 2:
            return None
        del by_tick[msg.tick]
        rgb, depth = halves["rgb"], halves["depth"]
        return rgb, self._frame(rgb, depth)

    def _frame(self, rgb: CameraImage, depth: CameraImage) -> RGBDFrame | None:
        where = (rgb.sim_time_s, *rgb.intrinsics, *rgb.position_m, *rgb.quaternion_wxyz)
        if len(rgb.intrinsics) != 9 or len(rgb.position_m) != 3 or len(rgb.quaternion_wxyz) != 4:
            self.drops.drop(f"camera/{rgb.camera}", "a frame whose intrinsics or pose has the wrong length")
            return None
        if not np.isfinite(where).all() or abs(np.linalg.norm(rgb.quaternion_wxyz) - 1.0) > 1e-3:
            self.drops.drop(f"camera/{rgb.camera}", "a frame with NaN or infinite values, or no rotation")
            return None
        try:
            depth_m = decode_image("depth", depth.data, depth.encoding, depth.width_px, depth.height_px)
            return RGBDFrame(
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
            return None
