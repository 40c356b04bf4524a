"""A camera's pose from its scene placement (`xyz`, `look_at`, `up`), in SAPIEN's and in ROS's optical convention.

SAPIEN's camera looks along its body's +x, with +y left and +z up. ROS names a
camera's optical frame `<camera>_optical_frame`: +z forward, +x right, +y down.
"""

from __future__ import annotations

import numpy as np
import sapien
from scipy.spatial.transform import Rotation

from fleet.record.camera_to_ros import optical_in_mount
from scenes.schema import CameraPlacement

# rotation taking optical axes (x right, y down, z forward) to SAPIEN camera axes (x forward, y left, z up)
OPTICAL_IN_BODY = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def _wxyz(matrix: np.ndarray) -> np.ndarray:
    x, y, z, w = Rotation.from_matrix(matrix).as_quat()
    return np.array([w, x, y, z])


OPTICAL_IN_BODY_POSE = sapien.Pose(q=_wxyz(OPTICAL_IN_BODY))


def body_pose(placement: CameraPlacement) -> sapien.Pose:
    """The SAPIEN camera body's pose in its mount's frame: at `xyz`, looking at `look_at`, `up` up in the image (the
    optical frame `/tf_static` gives, `optical_in_mount`, turned into SAPIEN's camera axes)."""
    position, (x, y, z, w) = optical_in_mount(placement)
    return sapien.Pose(position, [w, x, y, z]) * OPTICAL_IN_BODY_POSE.inv()


def optical_pose(body_in_world: sapien.Pose) -> tuple[np.ndarray, np.ndarray]:
    """The optical frame in the world, from the camera body's pose there: position and quaternion (wxyz)."""
    optical = body_in_world * OPTICAL_IN_BODY_POSE
    return np.asarray(optical.p, float), np.asarray(optical.q, float)
