"""Reading TF as a ROS tool does: a transform as a matrix, and a frame composed up its tree to the root."""

import numpy as np
import pinocchio as pin


def matrix_of(t) -> np.ndarray:
    """4x4 pose of a `geometry_msgs/TransformStamped` (child in its header's frame)."""
    q = t.transform.rotation
    m = np.eye(4)
    m[:3, :3] = pin.Quaternion(q.w, q.x, q.y, q.z).toRotationMatrix()
    m[:3, 3] = (t.transform.translation.x, t.transform.translation.y, t.transform.translation.z)
    return m


def up_to_root(frame: str, by_child: dict) -> tuple[str, np.ndarray]:
    """The root frame `frame` hangs from, and `frame`'s pose in it (transforms keyed by child frame)."""
    root_from_frame = np.eye(4)
    while frame in by_child:
        root_from_frame = matrix_of(by_child[frame]) @ root_from_frame
        frame = by_child[frame].header.frame_id
    return frame, root_from_frame
