"""Camera images off the bus made into RGB-D frames: a camera's colour and depth of one tick paired, checked and
decoded (`perception.rgbd.RGBDFrame`). Anything that cannot be a frame of the cameras asked for is dropped and
counted."""

from __future__ import annotations

import numpy as np

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.images import decode_image
from fleet.bus.messages import CameraImage
from perception.rgbd import RGBDFrame


class RGBDPairs:
    """Pairs `cameras`' colour and depth images by tick (`take`); a half whose other half never came is forgotten
    once a half of another tick arrives."""

    def __init__(self, cameras: list[str], drops: DropCounter) -> None:
        self.drops = drops
        self._decoder = Decoder(CameraImage, drops)
        self._halves: dict[str, dict[str, CameraImage]] = {name: {} for name in cameras}
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
        halves = self._halves[msg.camera]
        if any(h.tick != msg.tick for h in halves.values()):
            halves.clear()  # a half whose other half never came: that frame is lost
        halves[msg.kind] = msg
        if len(halves) < 2:
            return None
        rgb, depth = halves.pop("rgb"), halves.pop("depth")
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
