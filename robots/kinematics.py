"""Kinematics of one arm model with Pinocchio: frame poses and Jacobians, in the arm's base frame.

Poses are 4x4 homogeneous matrices `transform_frame_to_base`; multiply by the
arm's `transform_base_to_world` to get world poses. Joint vectors `q` cover all
of the model's joints in URDF order (arm joints then gripper joints for the
registered robots); `arm_q` helpers pick out the arm joints.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from robots.built_once import BuiltOnce
from robots.spec import RobotSpec


class KinematicModel(BuiltOnce):
    """Pinocchio model and data of one robot, with name lookups that list valid names on error (pickled as its
    robot: `robots.built_once`)."""

    def __init__(self, spec: RobotSpec) -> None:
        self.spec = spec
        self.model: pin.Model = pin.buildModelFromXML(spec.urdf_text())
        self.data: pin.Data = self.model.createData()
        self.tool_frame_id = self.frame_id(spec.tool_frame)
        self.arm_q_index = np.array([self._q_index(j) for j in spec.arm_joints])
        self.gripper_q_index = np.array([self._q_index(j) for j in spec.gripper_joints])
        self.lower = self.model.lowerPositionLimit.copy()
        self.upper = self.model.upperPositionLimit.copy()
        self.velocity_limit = self.model.velocityLimit.copy()
        # the arm joints' velocity limits, in the spec's joint order (by velocity index: a joint's `idx_v`)
        self.arm_velocity_limit = np.array(
            [self.velocity_limit[self.model.joints[self.model.getJointId(j)].idx_v] for j in spec.arm_joints]
        )
        self._closed_q = pin.neutral(self.model)  # the neutral configuration with the gripper closed
        self._closed_q[self.gripper_q_index] = spec.gripper_closed
        self._pan: tuple[np.ndarray, float] | None = None
        self._built_from((spec,), self.built_key(spec))

    @classmethod
    def built_key(cls, spec: RobotSpec) -> int:
        return id(spec)

    def first_joint_axis(self) -> tuple[np.ndarray, float]:
        """Where the first arm joint's axis stands in the base frame (its origin at the home pose) and +1 or -1 as
        it turns about +z or -z: the joint that aims the arm (every registered arm's is vertical)."""
        if self._pan is None:
            q = self.full_q(np.asarray(self.spec.home_q, float))
            joint = self.model.getJointId(self.spec.arm_joints[0])
            pin.computeJointJacobians(self.model, self.data, q)
            column = pin.getJointJacobian(self.model, self.data, joint, pin.ReferenceFrame.WORLD)[
                :, self.model.joints[joint].idx_v
            ]
            # angular part: the axis
            self._pan = (self.data.oMi[joint].translation.copy(), 1.0 if column[5] >= 0 else -1.0)
        return self._pan

    @property
    def nq(self) -> int:
        return self.model.nq

    def joint_names(self) -> list[str]:
        """Names of the joints in q order."""
        return [self.model.names[i] for i in range(1, self.model.njoints)]

    def frame_names(self) -> list[str]:
        return [f.name for f in self.model.frames]

    def frame_id(self, name: str) -> int:
        if not self.model.existFrame(name):
            raise KeyError(f"no frame {name!r} in {self.spec.uid}; frames: {', '.join(self.frame_names())}")
        return self.model.getFrameId(name)

    def _q_index(self, joint_name: str) -> int:
        if not self.model.existJointName(joint_name):
            raise KeyError(f"no joint {joint_name!r} in {self.spec.uid}; joints: {', '.join(self.joint_names())}")
        return self.model.joints[self.model.getJointId(joint_name)].idx_q

    def full_q(self, arm_q: np.ndarray, gripper_q: np.ndarray | None = None) -> np.ndarray:
        """A full configuration from arm joints (and gripper joints, else their closed values)."""
        q = self._closed_q.copy()
        q[self.arm_q_index] = arm_q
        if gripper_q is not None:
            q[self.gripper_q_index] = gripper_q
        return q

    def frame_pose(self, q: np.ndarray, frame: str | int | None = None) -> np.ndarray:
        """4x4 pose of a frame (default: the tool) in the base frame."""
        fid = self.tool_frame_id if frame is None else (frame if isinstance(frame, int) else self.frame_id(frame))
        pin.forwardKinematics(self.model, self.data, q)
        return pin.updateFramePlacement(self.model, self.data, fid).homogeneous

    def link_poses(self, q: np.ndarray) -> dict[str, np.ndarray]:
        """4x4 base-frame pose of every body (link) frame, by link name."""
        pin.framesForwardKinematics(self.model, self.data, q)
        return {
            f.name: self.data.oMf[i].homogeneous
            for i, f in enumerate(self.model.frames)
            if f.type == pin.FrameType.BODY
        }

    def frame_jacobian(self, q: np.ndarray, frame: str | int | None = None) -> np.ndarray:
        """6 x nv Jacobian of a frame, expressed in a frame at the frame's origin aligned with the base (linear;
        angular)."""
        fid = self.tool_frame_id if frame is None else (frame if isinstance(frame, int) else self.frame_id(frame))
        return pin.computeFrameJacobian(self.model, self.data, q, fid, pin.LOCAL_WORLD_ALIGNED)

    def clamp(self, q: np.ndarray) -> np.ndarray:
        return np.clip(q, self.lower, self.upper)


def _se3(transform: np.ndarray) -> pin.SE3:
    transform = np.asarray(transform, float)
    return pin.SE3(transform[:3, :3].copy(), transform[:3, 3].copy())


class PlacedFrames(BuiltOnce):
    """World poses of fixed frames on an arm's links (e.g. its collision shapes), from one forward-kinematics pass.

    A copy of the arm's Pinocchio model carries the base's placement in the world and one frame per pose asked
    for, so a configuration's poses cost one pass and one read per frame: no per-frame products in numpy (the
    collision guard places every arm of a cell this way, every env step). Pickled as what it was built from."""

    def __init__(
        self, km: KinematicModel, transform_base_to_world: np.ndarray, frames: list[tuple[str, np.ndarray]]
    ) -> None:
        """`frames`: (link name, `transform_frame_to_link`) for each pose, in the order `poses` returns them."""
        self.model = pin.Model(km.model)
        base = _se3(transform_base_to_world)
        for joint in range(1, self.model.njoints):  # joints hanging from the root move with the base
            if self.model.parents[joint] == 0:
                self.model.jointPlacements[joint] = base * self.model.jointPlacements[joint]
        self.frame_ids = []
        for i, (link, transform_frame_to_link) in enumerate(frames):
            parent = self.model.frames[km.frame_id(link)]
            placement = parent.placement * _se3(transform_frame_to_link)
            if parent.parentJoint == 0:  # fixed to the root: the base placement is not in any joint
                placement = base * placement
            name = f"placed_{i}_{link}"
            self.frame_ids.append(
                self.model.addFrame(pin.Frame(name, parent.parentJoint, placement, pin.FrameType.OP_FRAME))
            )
        self.data = self.model.createData()
        # the arguments are kept (and with them the model, so the robot the key names by id lives as long)
        args = (km, np.array(transform_base_to_world, float), [(link, np.array(t, float)) for link, t in frames])
        self._built_from(args, self.built_key(*args))

    @classmethod
    def built_key(
        cls, km: KinematicModel, transform_base_to_world: np.ndarray, frames: list[tuple[str, np.ndarray]]
    ) -> tuple:
        placed = tuple((link, np.asarray(t, float).tobytes()) for link, t in frames)
        return (id(km.spec), np.asarray(transform_base_to_world, float).tobytes(), placed)

    def poses(self, q: np.ndarray) -> np.ndarray:
        """(n, 4, 4) world poses of the frames for the full configuration `q`."""
        pin.forwardKinematics(self.model, self.data, q)
        update, model, data = pin.updateFramePlacement, self.model, self.data
        return np.array([update(model, data, fid).homogeneous for fid in self.frame_ids])
