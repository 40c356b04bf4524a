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
LIMIT_TOLERANCE_RAD = 1e-9  # a target this close to a joint limit is at it


@dataclass(frozen=True)
class JointTargets:
    """Where the arm's joints should go, and how far open the gripper should be (0 closed, 1 open)."""

    q: np.ndarray
    gripper_opening: float


class ActionTranslator:
    """Keeps the joint targets of arms of one model and moves them by each step's actions (`joint_delta` or
    `ee_delta`).

    One row per arm, in the order of the base transforms given: the env translates every arm of a model in one
    numpy pass (per-arm calls cost it more than the arithmetic); an arm's own process keeps one row.
    """

    def __init__(self, spec: RobotSpec, transforms_base_to_world: np.ndarray | list[np.ndarray], mode: str) -> None:
        """`transforms_base_to_world`: one 4x4 transform, or one per arm."""
        if mode not in CONTINUOUS_MODES:
            raise ValueError(
                f"action mode {mode!r} has no joint-target translation; valid: {', '.join(CONTINUOUS_MODES)}"
            )
        self.mode = mode
        self.kinematics = KinematicModel(spec)
        n = spec.arm_dof
        self.lower = self.kinematics.lower[self.kinematics.arm_q_index]
        self.upper = self.kinematics.upper[self.kinematics.arm_q_index]
        self.rotations_base_to_world = np.asarray(transforms_base_to_world, float).reshape(-1, 4, 4)[:, :3, :3]
        self.arms = len(self.rotations_base_to_world)
        self.action_size = (3 if mode == "ee_delta" else n) + 1
        self._inside_lower, self._inside_upper = self.lower + LIMIT_TOLERANCE_RAD, self.upper - LIMIT_TOLERANCE_RAD
        self.q_target = np.zeros((self.arms, n))  # rows: arms
        self.opening = np.ones(self.arms)

    def reset(self, q_arms: np.ndarray) -> None:
        """Start from the arms' joints as they are (one row per arm; a vector for one arm), grippers open."""
        self.q_target = np.clip(np.asarray(q_arms, float).reshape(self.arms, -1), self.lower, self.upper)
        self.opening = np.ones(self.arms)

    def apply(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Move the targets by one action per arm (rows; a vector for one arm), each entry clipped to [-1, 1];
        returns the joint targets (a row per arm) and the gripper openings. Both are new arrays each call."""
        actions = np.asarray(actions, float)
        if actions.shape != (self.arms, self.action_size) and not (
            self.arms == 1 and actions.shape == (self.action_size,)
        ):
            raise ValueError(
                f"a {self.mode} action has {self.action_size} entries (one row per arm, {self.arms} here), got shape "
                f"{actions.shape}"
            )
        # np.clip's own overhead is twice these two ufuncs'
        actions = np.minimum(np.maximum(actions.reshape(self.arms, -1), -1.0), 1.0)
        self.q_target = np.minimum(
            np.maximum(self.q_target + self._joint_steps(actions[:, :-1]), self.lower), self.upper
        )
        self.opening = (actions[:, -1] + 1.0) / 2.0
        return self.q_target, self.opening

    def at_limit(self, q: np.ndarray) -> np.ndarray:
        """Per row of joint targets `q`: whether any stands at its limit (where `apply` clipped it)."""
        return ((q <= self._inside_lower) | (q >= self._inside_upper)).any(axis=-1)

    def _joint_steps(self, actions: np.ndarray) -> np.ndarray:
        """Joint target changes, a row per arm: direct, or from a claw step in the world frame by damped least
        squares."""
        if self.mode == "joint_delta":
            return actions * MAX_DELTA_RAD
        km = self.kinematics
        steps = np.empty_like(self.q_target)
        for i, (q, rotation, action) in enumerate(zip(self.q_target, self.rotations_base_to_world, actions)):
            step_base = rotation.T @ (action * MAX_EE_STEP_M)
            jacobian = km.frame_jacobian(km.full_q(q))[:3, km.arm_q_index]
            steps[i] = jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + EE_DAMPING * np.eye(3), step_base)
        return steps
