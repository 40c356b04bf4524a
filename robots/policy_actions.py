"""What a learning agent's continuous action means for one arm: joint targets and a gripper opening.

Pure computation on Pinocchio, so the env's in-process path and the per-arm
processes of `distributed=True` turn the same actions into the same targets,
bit for bit. Actions are in [-1, 1]; the last entry is the gripper (-1 closed, 1 open).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from robots.kinematics import KinematicModel
from robots.spec import RobotSpec

CONTINUOUS_MODES = ("joint_delta", "ee_delta")
MAX_DELTA_RAD = 0.05  # joint_delta: a joint target's step per control tick at full action
MAX_EE_STEP_M = 0.01  # ee_delta: the claw's step per control tick at full action
EE_DAMPING = 1e-3


@dataclass(frozen=True)
class JointTargets:
    """Where the arm's joints should go, and how far open the gripper should be (0 closed, 1 open)."""

    q: np.ndarray
    gripper_opening: float


class ActionTranslator:
    """Keeps an arm's joint targets and moves them by each action (`joint_delta` or `ee_delta`)."""

    def __init__(self, spec: RobotSpec, transform_base_to_world: np.ndarray, mode: str) -> None:
        if mode not in CONTINUOUS_MODES:
            raise ValueError(f"action mode {mode!r} has no joint-target translation; valid: {', '.join(CONTINUOUS_MODES)}")
        self.mode = mode
        self.kinematics = KinematicModel(spec)
        n = spec.arm_dof
        self.lower = self.kinematics.lower[self.kinematics.arm_q_index]
        self.upper = self.kinematics.upper[self.kinematics.arm_q_index]
        self.rotation_base_to_world = np.asarray(transform_base_to_world, float)[:3, :3]
        self.action_size = (3 if mode == "ee_delta" else n) + 1
        self.q_target = np.zeros(n)
        self.opening = 1.0

    def reset(self, q_arm: np.ndarray) -> None:
        """Start from the arm's joints as they are, gripper open."""
        self.q_target = np.clip(np.asarray(q_arm, float), self.lower, self.upper)
        self.opening = 1.0

    def apply(self, action: np.ndarray) -> JointTargets:
        """Move the targets by one action (clipped to [-1, 1]) and return them."""
        action = np.asarray(action, float).reshape(-1)
        if action.size != self.action_size:
            raise ValueError(f"{self.mode} action has {self.action_size} entries, got {action.size}")
        action = np.minimum(np.maximum(action, -1.0), 1.0)  # np.clip's own overhead is twice these two ufuncs'
        self.q_target = np.minimum(np.maximum(self.q_target + self._joint_step(action[:-1]), self.lower), self.upper)
        self.opening = (float(action[-1]) + 1.0) / 2.0
        return JointTargets(self.q_target.copy(), self.opening)

    def _joint_step(self, action: np.ndarray) -> np.ndarray:
        """Joint target change: direct, or from a claw step in the world frame by damped least squares."""
        if self.mode == "joint_delta":
            return action * MAX_DELTA_RAD
        km = self.kinematics
        step_base = self.rotation_base_to_world.T @ (action * MAX_EE_STEP_M)
        jacobian = km.frame_jacobian(km.full_q(self.q_target))[:3, km.arm_q_index]
        return jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + EE_DAMPING * np.eye(3), step_base)
