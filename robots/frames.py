"""Frame helpers: 4x4 transforms from positions, yaws and wxyz quaternions (via Pinocchio)."""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin


def rotation_from_wxyz(q_wxyz: np.ndarray) -> np.ndarray:
    """3x3 rotation of a quaternion given w first (SAPIEN and viser order)."""
    w, x, y, z = (float(v) for v in q_wxyz)
    return pin.Quaternion(w, x, y, z).normalized().toRotationMatrix()


def wxyz_from_rotation(rotation: np.ndarray) -> np.ndarray:
    """Quaternion w first of a 3x3 rotation (Pinocchio's coeffs() puts w last)."""
    x, y, z, w = pin.Quaternion(rotation).coeffs()
    return np.array([w, x, y, z])


def transform(position: np.ndarray, rotation: np.ndarray | None = None) -> np.ndarray:
    """4x4 homogeneous transform from a position and a rotation (identity if none)."""
    t = np.eye(4)
    t[:3, 3] = position
    if rotation is not None:
        t[:3, :3] = rotation
    return t


def yaw_transform(xyz: tuple[float, float, float], yaw_rad: float) -> np.ndarray:
    """4x4 transform of a placement on the floor: position and a yaw about +z."""
    return transform(np.asarray(xyz, float), pin.utils.rpyToMatrix(0.0, 0.0, yaw_rad))


def top_down_rotation(yaw_rad: float) -> np.ndarray:
    """A tool orientation with its approach axis (+z) pointing straight down, turned by `yaw_rad` about world z."""
    return pin.utils.rpyToMatrix(0.0, 0.0, yaw_rad) @ np.diag([1.0, -1.0, -1.0])


def wrap_angle(a: float) -> float:
    return (a + math.pi) % (2 * math.pi) - math.pi
