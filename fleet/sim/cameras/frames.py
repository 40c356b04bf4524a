"""A camera's frame: the images it made at one sim time, its intrinsics and where its optical frame stood."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from perception.rgbd import RGBDFrame, back_project


@dataclass(frozen=True)
class CameraFrame:
    """One camera's images at `sim_time_s`: RGB (uint8 HxWx3), depth (float32 HxW, metres along the optical axis,
    0 where nothing lies within far_m), segmentation (int32 HxW, ids of `fleet.sim.cameras.labels`), each None when
    the camera does not make it. `intrinsics` is the 3x3 pinhole matrix K; the optical frame (+z forward, +x right,
    +y down) stands at `position_m` with `quaternion_wxyz` in the world."""

    camera: str
    sim_time_s: float
    intrinsics: np.ndarray
    position_m: np.ndarray
    quaternion_wxyz: np.ndarray
    rgb: np.ndarray | None = None
    depth_m: np.ndarray | None = None
    segmentation: np.ndarray | None = None

    def images(self) -> dict[str, np.ndarray]:
        """The images this frame holds, by kind (`rgb`, `depth`, `segmentation`), in that order."""
        kinds = {"rgb": self.rgb, "depth": self.depth_m, "segmentation": self.segmentation}
        return {kind: image for kind, image in kinds.items() if image is not None}

    @property
    def size_px(self) -> tuple[int, int]:
        """(width, height)."""
        image = next(iter(self.images().values()))
        return image.shape[1], image.shape[0]

    def points_in_world(self, mask: np.ndarray | None = None) -> np.ndarray:
        """The depth image back-projected through the intrinsics into world points (N x 3), for the pixels of `mask`
        (default: every pixel with depth)."""
        if self.depth_m is None:
            raise ValueError(f"camera {self.camera!r} makes no depth image")
        return back_project(self.depth_m, self.intrinsics, self.position_m, self.quaternion_wxyz, mask)

    def rgbd(self) -> RGBDFrame:
        """What perception is given of this frame: colour, depth, intrinsics and pose; never the segmentation."""
        if self.rgb is None or self.depth_m is None:
            raise ValueError(f"camera {self.camera!r} makes no colour and depth images: perception needs both")
        return RGBDFrame(
            self.camera, self.sim_time_s, self.rgb, self.depth_m, self.intrinsics, self.position_m, self.quaternion_wxyz
        )
