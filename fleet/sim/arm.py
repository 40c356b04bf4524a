"""One arm in the SAPIEN scene: loaded from its URDF (collision only), driven by PD joint drives.

The drives compensate the arm's own weight, as real arm firmware does: the
links carry no gravity, while a held part (a separate body) keeps its weight.
"""

from __future__ import annotations

import math
import re
import tempfile
from pathlib import Path

import numpy as np
import sapien

from robots.spec import RobotSpec

SAME_ARM_IGNORE_BIT = 1 << 31


def collision_only_urdf(spec: RobotSpec) -> str:
    """The robot's URDF without <visual> elements: SAPIEN has no render device here to load them with."""
    return re.sub(r"<visual\b.*?</visual>", "", spec.urdf_text(), flags=re.S)


def yaw_pose(xyz: tuple[float, float, float], yaw_rad: float) -> sapien.Pose:
    """A SAPIEN pose from a position and a yaw about +z (quaternion wxyz)."""
    return sapien.Pose(list(xyz), [math.cos(yaw_rad / 2), 0.0, 0.0, math.sin(yaw_rad / 2)])


class SimArm:
    """An articulated arm with its drives; joint vectors are in the spec's arm + gripper joint order."""

    def __init__(
        self,
        scene: sapien.Scene,
        spec: RobotSpec,
        name: str,
        base_pose: sapien.Pose,
        arm_index: int,
        gain_scale: float = 1.0,
    ) -> None:
        self.name, self.spec = name, spec
        loader = scene.create_urdf_loader()
        loader.fix_root_link = True
        for link in spec.finger_links:
            loader.set_link_material(link, spec.finger_friction, spec.finger_friction, 0.0)
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / f"{spec.uid}.urdf"
            path.write_text(collision_only_urdf(spec))
            self.articulation = loader.load(str(path))
        self.articulation.set_name(name)
        self.articulation.set_root_pose(base_pose)
        self.base_pose = base_pose
        joints = {j.name: j for j in self.articulation.get_active_joints()}
        order = [j.name for j in self.articulation.get_active_joints()]
        names = list(spec.arm_joints) + list(spec.gripper_joints)
        missing = [n for n in names if n not in joints]
        if missing:
            raise KeyError(f"{spec.uid}: joints {missing} not in the URDF; active joints: {', '.join(order)}")
        self.joints = [joints[n] for n in names]
        self.qpos_index = np.array([order.index(n) for n in names])
        if np.array_equal(self.qpos_index, np.arange(len(names))):  # the usual case: the spec's order is SAPIEN's
            self.qpos_index = slice(0, len(names))  # a slice view costs less than a gather, every step
        self.links = {link.name: link for link in self.articulation.get_links()}
        self.tool_link = self.links[spec.tool_frame]
        for link in self.articulation.get_links():
            link.disable_gravity = True
            for shape in link.get_collision_shapes():
                groups = shape.get_collision_groups()
                groups[2] |= SAME_ARM_IGNORE_BIT
                groups[3] = (groups[3] & ~0xFFFF) | (arm_index + 1)
                shape.set_collision_groups(groups)
        n_arm = spec.arm_dof
        for i, joint in enumerate(self.joints):
            gains = spec.arm_gains if i < n_arm else spec.gripper_gains
            k = gain_scale if i < n_arm else 1.0  # a randomised scene may scale the arm's drives, never the claw's grip
            joint.set_drive_property(gains.stiffness * k, gains.damping * k, gains.force_limit, "force")
        self._position_targets = [
            math.nan
        ] * n_arm  # last written; NaN differs from any value, so the first write sets all
        self._velocity_targets = [math.nan] * n_arm
        self._gripper_targets = [math.nan] * len(spec.gripper_joints)
        self.set_qpos(np.concatenate([spec.home_q, spec.gripper_targets(1.0)]))

    def set_qpos(self, q: np.ndarray) -> None:
        """Teleport the joints (setup and state restore only) and hold them there."""
        full = self.articulation.get_qpos()
        full[self.qpos_index] = q
        self.articulation.set_qpos(full)
        self.articulation.set_qvel(np.zeros_like(full))
        self.set_targets(q[: self.spec.arm_dof], np.zeros(self.spec.arm_dof), q[self.spec.arm_dof :])

    def set_targets(self, arm_q: np.ndarray, arm_dq: np.ndarray, gripper_q: np.ndarray | tuple[float, ...]) -> None:
        """Drive targets: arm joint positions and velocities, gripper joint positions.

        A target equal to the one last written is skipped (the articulation never sleeps:
        `sleep_threshold` 0), so an arm holding still costs no calls into SAPIEN. Plain floats:
        a handful of numbers costs less as a list than as numpy arrays.
        """
        n = self.spec.arm_dof
        position, velocity = np.asarray(arm_q, float).tolist(), np.asarray(arm_dq, float).tolist()
        gripper = list(map(float, gripper_q))
        if position != self._position_targets:  # one comparison of lists before any per-joint one
            for joint, new, old in zip(self.joints, position, self._position_targets):
                if new != old:
                    joint.set_drive_target(new)
        if velocity != self._velocity_targets:
            for joint, new, old in zip(self.joints, velocity, self._velocity_targets):
                if new != old:
                    joint.set_drive_velocity_target(new)
        if gripper != self._gripper_targets:
            for joint, new, old in zip(self.joints[n:], gripper, self._gripper_targets):
                if new != old:
                    joint.set_drive_target(new)
        self._position_targets, self._velocity_targets, self._gripper_targets = position, velocity, gripper

    def written_targets(self) -> tuple[list[float], list[float], list[float]]:
        """The drive targets last written: arm positions, arm velocities, gripper positions."""
        return self._position_targets, self._velocity_targets, self._gripper_targets

    def set_gripper_effort(self, force_limit: float) -> None:
        """The gripper drives' force limit (a GripperCommand goal's max effort); stiffness and damping stay."""
        gains = self.spec.gripper_gains
        for joint in self.joints[self.spec.arm_dof :]:
            joint.set_drive_property(gains.stiffness, gains.damping, force_limit, "force")

    def gripper_force_limit(self) -> float:
        """The gripper drives' force limit now (the last grasp's effort, or the robot's own)."""
        return float(self.joints[self.spec.arm_dof].force_limit) if len(self.joints) > self.spec.arm_dof else 0.0

    def restore_targets(self, position: np.ndarray, velocity: np.ndarray) -> None:
        """Write every joint's drive targets (a state restore), position and velocity, arm then gripper joints."""
        position, velocity = np.asarray(position, float).tolist(), np.asarray(velocity, float).tolist()
        for j, t, v in zip(self.joints, position, velocity):
            j.set_drive_target(t)
            j.set_drive_velocity_target(v)
        n = self.spec.arm_dof
        self._position_targets, self._velocity_targets, self._gripper_targets = position[:n], velocity[:n], position[n:]

    def qpos(self) -> np.ndarray:
        return self.articulation.get_qpos()[self.qpos_index].astype(float)

    def qvel(self) -> np.ndarray:
        return self.articulation.get_qvel()[self.qpos_index].astype(float)

    def drive_targets(self) -> np.ndarray:
        return np.array([j.get_drive_target()[0] for j in self.joints], dtype=float)

    def drive_velocity_targets(self) -> np.ndarray:
        return np.array([j.get_drive_velocity_target()[0] for j in self.joints], dtype=float)

    def joint_limits(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper position limits of the arm + gripper joints."""
        limits = self.articulation.get_qlimits()[self.qpos_index]
        return limits[:, 0].astype(float), limits[:, 1].astype(float)

    def tool_pose_world(self) -> sapien.Pose:
        return self.tool_link.entity_pose

    def link_shapes(self) -> set:
        """Every collision shape of the arm (to tell its contacts apart)."""
        return {s for link in self.articulation.get_links() for s in link.get_collision_shapes()}
