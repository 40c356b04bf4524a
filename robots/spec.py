"""A robot declared as plain facts: URDF, joints, tool frame, keyframes, gripper and drive gains."""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class DriveGains:
    """PD drive of a joint group: stiffness (N*m/rad or N/m), damping, and the force/torque limit."""

    stiffness: float
    damping: float
    force_limit: float


@dataclass(frozen=True)
class RobotSpec:
    """Everything the project needs to know of an arm model; registered by `uid`.

    The gripper is commanded as an opening in [0, 1] (0 closed, 1 open),
    mapped linearly onto each gripper joint between `gripper_closed` and `gripper_open`.
    """

    uid: str
    summary: str
    urdf_path: Callable[[], Path]
    arm_joints: tuple[str, ...]
    gripper_joints: tuple[str, ...]
    tool_frame: str
    home_q: tuple[float, ...]
    gripper_open: tuple[float, ...]
    gripper_closed: tuple[float, ...]
    grasp_width_m: tuple[float, float]
    arm_gains: DriveGains
    gripper_gains: DriveGains
    finger_links: tuple[str, ...]
    finger_friction: float = 1.2
    approach_axis_tool: tuple[float, float, float] = (0.0, 0.0, 1.0)
    closing_axis_tool: tuple[float, float, float] = (0.0, 1.0, 0.0)
    width_per_gripper_unit_m: float | None = None
    fingertip_below_tool_m: float = 0.0
    package_prefix: str | None = None
    package_root_dir: Path | None = None
    """Where `package_prefix` URIs resolve (default: the folder two above the URDF's, as example-robot-data lays
    out)."""
    keyframes: dict[str, tuple[float, ...]] = field(default_factory=dict)
    needs_extra: str | None = None
    fixed_jaw_face_m: float | None = None
    """A gripper with one fixed jaw (SO-101): where that jaw's inner face lies along `closing_axis_tool` (the way the
    moving jaw closes) from the tool frame; a part's centre goes half its width short of it. None: the jaws close
    symmetrically about the tool frame."""
    grip_depth_m: float = 0.0
    """How far behind the tool frame (against the approach axis) a part's centre is held: a tool frame at the jaws'
    tips (SO-101) holds parts this far in, where the jaws overlap them."""
    carry_tilted: bool = False
    """Place leaning at least as far as the pick did (the claw is not turned upright on the way): an arm that holds
    parts at its jaws' tips keeps them better."""
    pick_timing: dict[str, float] = field(default_factory=dict)
    """This robot's values for fields of the pick skill's timing (`PickPlaceTiming`: speeds, hover and lift heights)."""
    max_approach_tilt_deg: float = 0.0
    """How far from straight down the claw may lean (outwards, away from the base) where straight down is out of
    reach."""
    match_yaw: bool = True
    """An arm of fewer than six joints also turns its claw to the grasp's yaw where it can (else only the approach
    axis)."""
    declared_in: str = "clawfleet"
    """Where the declaration came from: clawfleet itself, a robot file's path, or an entry point."""

    @property
    def arm_dof(self) -> int:
        return len(self.arm_joints)

    def gripper_targets(self, opening: float) -> tuple[float, ...]:
        """Joint targets of the gripper for a normalised opening (clamped to [0, 1])."""
        a = min(max(opening, 0.0), 1.0)
        return tuple(c + a * (o - c) for c, o in zip(self.gripper_closed, self.gripper_open))

    def opening_of(self, gripper_q) -> float:
        """The normalised opening of gripper joints `gripper_q`: the mean of each joint's way from closed to open."""
        closed, opened = np.asarray(self.gripper_closed, float), np.asarray(self.gripper_open, float)
        run = np.where(np.abs(opened - closed) > 1e-12, opened - closed, 1.0)
        return float(np.mean((np.asarray(gripper_q, float) - closed) / run))

    def opening_for_width(self, width_m: float) -> float:
        """The normalised opening that spaces the fingers `width_m` apart (fully open if unknown)."""
        if self.width_per_gripper_unit_m is None:
            return 1.0
        c, o = self.gripper_closed[0], self.gripper_open[0]
        return (width_m / self.width_per_gripper_unit_m - c) / (o - c)

    def grasp_centre_tool(self, width_m: float, fixed_jaw_gap_m: float = 0.0) -> tuple[float, float, float]:
        """Where a part `width_m` wide sits between the jaws, in the tool frame (the origin for symmetric jaws); a
        fixed jaw comes down `fixed_jaw_gap_m` clear of the part's face (the part aimed that much further in)."""
        k = 0.0 if self.fixed_jaw_face_m is None else self.fixed_jaw_face_m - width_m / 2 - fixed_jaw_gap_m
        return tuple(
            float(c * k - a * self.grip_depth_m) for c, a in zip(self.closing_axis_tool, self.approach_axis_tool)
        )

    def link_names(self) -> tuple[str, ...]:
        """Every link the URDF declares, in file order (what a camera may be mounted on)."""
        return tuple(re.findall(r"<link\s+name\s*=\s*[\"']([^\"']+)[\"']", self.urdf_text()))

    def urdf_text(self) -> str:
        """The URDF with package URIs resolved and <mimic> removed: every joint is driven on its own."""
        path = self.urdf_path()
        text = path.read_text()
        if self.package_prefix is not None:
            root = self.package_root_dir if self.package_root_dir is not None else path.parents[2]
            text = text.replace(self.package_prefix, str(root) + "/")
        return re.sub(r"<mimic[^>]*/>", "", text)
