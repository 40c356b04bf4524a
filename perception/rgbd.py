"""What a camera gives perception: colour and depth images at one sim time, its intrinsics and where its optical
frame stood; and the back-projection of depth pixels into the world."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation


def back_project(
    depth_m: np.ndarray,
    intrinsics: np.ndarray,
    position_m: np.ndarray,
    quaternion_wxyz: np.ndarray,
    mask: np.ndarray | None = None,
) -> np.ndarray:
    """World points (N x 3) of the depth pixels of `mask` (default: every pixel with depth; 0 is no depth), through
    the pinhole `intrinsics` of an optical frame (+z forward, +x right, +y down) at `position_m`, `quaternion_wxyz`."""
    rows, cols = np.nonzero((depth_m > 0) if mask is None else (mask & (depth_m > 0)))
    z = depth_m[rows, cols].astype(float)
    k = intrinsics
    optical = np.column_stack([(cols + 0.5 - k[0, 2]) / k[0, 0] * z, (rows + 0.5 - k[1, 2]) / k[1, 1] * z, z])
    w, x, y, q = quaternion_wxyz
    return Rotation.from_quat([x, y, q, w]).apply(optical) + np.asarray(position_m, float)


@dataclass(frozen=True)
class RGBDFrame:
    """One camera's colour (uint8 HxWx3) and depth (float32 HxW, metres along the optical axis, 0 where nothing lies
    within range) at `sim_time_s`; `intrinsics` is the 3x3 pinhole matrix K, the optical frame stands at
    `position_m` with `quaternion_wxyz` in the world."""

    camera: str
    sim_time_s: float
    rgb: np.ndarray
    depth_m: np.ndarray
    intrinsics: np.ndarray
    position_m: np.ndarray
    quaternion_wxyz: np.ndarray

    def __post_init__(self) -> None:
        if self.rgb.shape[:2] != self.depth_m.shape or self.rgb.ndim != 3 or self.rgb.shape[2] != 3:
            raise ValueError(
                f"camera {self.camera!r}: colour {self.rgb.shape} and depth {self.depth_m.shape} differ in size"
            )

    def points_in_world(self, mask: np.ndarray | None = None) -> np.ndarray:
        """The depth pixels of `mask` (default: all with depth) as world points (N x 3)."""
        return back_project(self.depth_m, self.intrinsics, self.position_m, self.quaternion_wxyz, mask)
