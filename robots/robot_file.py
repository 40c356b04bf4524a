"""A robot declared in a YAML file: the same plain facts as `RobotSpec`, checked against its URDF with Pinocchio.

A user's own arm runs without a code change: a scene names the file in
`robot_files` (or a package registers it by the `clawfleet.robots` entry point),
and its arms use the file's `uid` as their model. Every mistake is one line
naming the file and the field: a joint or frame the URDF lacks (with the valid
names), a home pose or gripper position beyond a joint's limits, rows of the
wrong length. Units are in the field names.
"""

from __future__ import annotations

import dataclasses
import difflib
from pathlib import Path
from typing import Annotated

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from robots.spec import DriveGains, RobotSpec
from scenes.schema import NAME_PATTERN, FileName
from scenes.yaml_file import DeclarationError, named_in, read_declaration, regular_file

MAX_ROBOT_FILE_BYTES = 100_000
PACKAGE_URI = "package://"
LIMIT_SLACK = 1e-6

Finite = Annotated[float, Field(allow_inf_nan=False)]
Positive = Annotated[float, Field(gt=0, allow_inf_nan=False)]
JointName = Annotated[str, Field(min_length=1, max_length=200)]


class RobotFileError(DeclarationError):
    """A robot file that cannot be used: file, field path and reason on one line."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Gains(_Strict):
    """PD drive of a joint group: stiffness (N*m/rad or N/m), damping (N*m*s/rad or N*s/m), force limit (N*m or N)."""

    stiffness: Positive
    damping: Annotated[float, Field(ge=0, allow_inf_nan=False)]
    force_limit: Positive

    def drive(self) -> DriveGains:
        return DriveGains(self.stiffness, self.damping, self.force_limit)


class RobotFile(_Strict):
    """The fields of a robot file (see docs/robots.md); joint positions are in the joint's unit (rad or m)."""

    uid: Annotated[str, Field(pattern=NAME_PATTERN, max_length=40)]
    summary: str = ""
    urdf: FileName
    """The URDF, relative to the robot file (or absolute)."""
    package_root: FileName | None = None
    """Folder that `package://NAME/...` URIs resolve in (as `<package_root>/NAME/...`), relative to the robot file."""
    arm_joints: Annotated[list[JointName], Field(min_length=1, max_length=12)]
    gripper_joints: Annotated[list[JointName], Field(min_length=1, max_length=4)]
    tool_frame: JointName
    home_q: list[Finite]
    gripper_open_q: list[Finite]
    gripper_closed_q: list[Finite]
    grasp_width_m: tuple[Positive, Positive]
    reach_m: None = None
    """Not declared: measured from the kinematics (`robots.measured_reach`); a file that gives it is told so."""
    arm_gains: Gains
    gripper_gains: Gains
    finger_links: Annotated[list[JointName], Field(min_length=1, max_length=4)]
    finger_friction: Annotated[float, Field(gt=0, le=5.0)] = 1.2
    approach_axis_tool: tuple[Finite, Finite, Finite] = (0.0, 0.0, 1.0)
    closing_axis_tool: tuple[Finite, Finite, Finite] = (0.0, 1.0, 0.0)
    width_per_gripper_unit_m: Positive | None = None
    fingertip_below_tool_m: Annotated[float, Field(ge=0, le=0.5)] = 0.0
    keyframes: dict[Annotated[str, Field(pattern=NAME_PATTERN)], list[Finite]] = {}
    max_approach_tilt_deg: Annotated[float, Field(ge=0, le=80)] = 0.0
    """How far the claw may lean outwards where it cannot point straight down (an arm of few joints or short reach)."""
    fixed_jaw_face_m: Annotated[float, Field(ge=-0.2, le=0.2, allow_inf_nan=False)] | None = None
    """A gripper with one fixed jaw: where its inner face lies along closing_axis_tool from the tool frame."""
    grip_depth_m: Annotated[float, Field(ge=0, le=0.2)] = 0.0
    """How far behind the tool frame, against the approach axis, parts are held."""
    carry_tilted: bool = False
    """Place leaning at least as far as the pick did (parts held at the jaws' tips stay in)."""
    match_yaw: bool = True
    """An arm of fewer than six joints turns its claw to the grasp yaw with its last joint."""
    pick_timing: dict[str, Annotated[float, Field(gt=0, allow_inf_nan=False)]] = {}
    """Values for the pick skill's timing fields (hover_m, lift_m, approach_speed, transfer_speed, lift_s, ...)."""

    @field_validator("reach_m", mode="before")
    @classmethod
    def _reach_is_measured(cls, value: object) -> None:
        if value is not None:
            raise ValueError("the reach is measured from the arm's kinematics, not declared: remove this field")
        return None

    @field_validator("pick_timing")
    @classmethod
    def _timing_fields(cls, v: dict[str, float]) -> dict[str, float]:
        from robots.skills.pick_place import PickPlaceTiming  # the skill's own fields: no list to keep in step

        valid = [f.name for f in dataclasses.fields(PickPlaceTiming)]
        for name in v:
            if name not in valid:
                raise ValueError(f"no timing field {name!r}; fields: {', '.join(valid)}")
        return v

    @field_validator("approach_axis_tool", "closing_axis_tool")
    @classmethod
    def _unit(cls, v: tuple[float, float, float]) -> tuple[float, float, float]:
        n = float(np.linalg.norm(v))
        if abs(n - 1.0) > 1e-3:
            raise ValueError(f"an axis must be a unit vector (its length is {n:.3g})")
        return v

    @model_validator(mode="after")
    def _rows(self) -> RobotFile:
        lo, hi = self.grasp_width_m
        if lo >= hi:
            raise ValueError(f"grasp_width_m: the smallest width ({lo:g}) must be below the largest ({hi:g})")
        named = self.arm_joints + self.gripper_joints
        twice = sorted({j for j in named if named.count(j) > 1})
        if twice:
            raise ValueError(f"joints named twice in arm_joints and gripper_joints: {', '.join(twice)}")
        return self


def load_robot_file(path: Path) -> RobotSpec:
    """The robot a YAML file declares, checked against its URDF; raises `RobotFileError` naming file and field."""
    path = regular_file(Path(path), "robot", RobotFileError).resolve()
    label = str(path)
    decl = read_declaration(path, label, "robot", MAX_ROBOT_FILE_BYTES, RobotFile, RobotFileError)
    urdf = named_in(path, decl.urdf)
    if not urdf.is_file():
        raise RobotFileError(label, "urdf", f"no such file {urdf}")
    package_root = named_in(path, decl.package_root) if decl.package_root is not None else None
    if package_root is not None and not package_root.is_dir():
        raise RobotFileError(label, "package_root", f"no such folder {package_root}")
    spec = RobotSpec(
        uid=decl.uid,
        summary=decl.summary or f"declared in {path.name}",
        urdf_path=lambda: urdf,
        arm_joints=tuple(decl.arm_joints),
        gripper_joints=tuple(decl.gripper_joints),
        tool_frame=decl.tool_frame,
        home_q=tuple(decl.home_q),
        gripper_open=tuple(decl.gripper_open_q),
        gripper_closed=tuple(decl.gripper_closed_q),
        grasp_width_m=decl.grasp_width_m,
        arm_gains=decl.arm_gains.drive(),
        gripper_gains=decl.gripper_gains.drive(),
        finger_links=tuple(decl.finger_links),
        finger_friction=decl.finger_friction,
        approach_axis_tool=decl.approach_axis_tool,
        closing_axis_tool=decl.closing_axis_tool,
        width_per_gripper_unit_m=decl.width_per_gripper_unit_m,
        fingertip_below_tool_m=decl.fingertip_below_tool_m,
        package_prefix=PACKAGE_URI if package_root is not None else None,
        package_root_dir=package_root,
        keyframes={k: tuple(v) for k, v in decl.keyframes.items()},
        max_approach_tilt_deg=decl.max_approach_tilt_deg,
        fixed_jaw_face_m=decl.fixed_jaw_face_m,
        grip_depth_m=decl.grip_depth_m,
        carry_tilted=decl.carry_tilted,
        match_yaw=decl.match_yaw,
        pick_timing=dict(decl.pick_timing),
        declared_in=label,
    )
    check_against_urdf(spec, decl, label)
    return spec


def _names_hint(name: str, valid: list[str]) -> str:
    close = difflib.get_close_matches(name, valid, n=3)
    shown = close if close else valid[:40]
    return (
        ("did you mean " if close else "valid: ") + ", ".join(shown) + (" ..." if not close and len(valid) > 40 else "")
    )


def _check_meshes(spec: RobotSpec, label: str) -> None:
    """Every mesh the URDF names exists (the physics would only log a missing one and leave the link without it)."""
    import xml.etree.ElementTree as ET

    urdf_dir = spec.urdf_path().parent
    for link in ET.fromstring(spec.urdf_text()).iter("link"):
        for mesh in link.iter("mesh"):
            name = (mesh.get("filename") or "").removeprefix("file://")
            path = Path(name) if Path(name).is_absolute() else urdf_dir / name
            if not name or name.startswith(PACKAGE_URI) or not path.is_file():
                raise RobotFileError(
                    label,
                    "urdf",
                    f"link {link.get('name')!r} names a mesh that is not there: {name or '(no filename)'}"
                    + (" (give package_root for package:// URIs)" if name.startswith(PACKAGE_URI) else ""),
                )


def check_against_urdf(spec: RobotSpec, decl: RobotFile, label: str) -> None:
    """Joints, frames, links and positions of the declaration as the URDF has them (Pinocchio reads it)."""
    import pinocchio as pin  # only when a robot file is read: listing robots needs no kinematics

    try:
        model = pin.buildModelFromXML(spec.urdf_text())
    except Exception as exc:  # Pinocchio's parser raises bare RuntimeError/ValueError with C++ detail
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise RobotFileError(label, "urdf", f"not a URDF Pinocchio can read: {first}") from None
    _check_meshes(spec, label)
    joints = [model.names[i] for i in range(1, model.njoints)]
    for field, names in (("arm_joints", decl.arm_joints), ("gripper_joints", decl.gripper_joints)):
        for i, name in enumerate(names):
            if name not in joints:
                raise RobotFileError(
                    label, f"{field}.{i}", f"no movable joint {name!r} in the URDF; {_names_hint(name, joints)}"
                )
            if model.joints[model.getJointId(name)].nq != 1:
                raise RobotFileError(
                    label, f"{field}.{i}", f"joint {name!r} is not a single revolute or prismatic joint"
                )
    frames = [f.name for f in model.frames]
    if not model.existFrame(decl.tool_frame):
        raise RobotFileError(
            label, "tool_frame", f"no frame {decl.tool_frame!r} in the URDF; {_names_hint(decl.tool_frame, frames)}"
        )
    links = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
    for i, name in enumerate(decl.finger_links):
        if name not in links:
            raise RobotFileError(
                label, f"finger_links.{i}", f"no link {name!r} in the URDF; {_names_hint(name, links)}"
            )
    rows = [
        ("home_q", decl.home_q, decl.arm_joints),
        ("gripper_open_q", decl.gripper_open_q, decl.gripper_joints),
        ("gripper_closed_q", decl.gripper_closed_q, decl.gripper_joints),
    ]
    rows += [(f"keyframes.{k}", v, decl.arm_joints) for k, v in decl.keyframes.items()]
    for field, values, names in rows:
        if len(values) != len(names):
            raise RobotFileError(label, field, f"{len(values)} values for {len(names)} joints ({', '.join(names)})")
        for i, (value, name) in enumerate(zip(values, names)):
            j = model.joints[model.getJointId(name)].idx_q
            lo, hi = float(model.lowerPositionLimit[j]), float(model.upperPositionLimit[j])
            if not lo - LIMIT_SLACK <= value <= hi + LIMIT_SLACK:
                raise RobotFileError(
                    label, f"{field}.{i}", f"{value:g} is beyond joint {name!r}'s limits [{lo:g}, {hi:g}]"
                )
    if decl.gripper_open_q == decl.gripper_closed_q:
        raise RobotFileError(label, "gripper_closed_q", "equal to gripper_open_q: the gripper would never move")
