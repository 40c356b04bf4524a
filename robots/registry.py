"""The robot registry: `openclaw` always; `so101` and `panda` from the `models` extra (example-robot-data);
robots that installed packages declare under the `clawfleet.robots` entry point group; robot files a scene names.

An entry point may name a `RobotSpec`, a function returning one, or the path of a robot YAML file. One that
cannot be loaded is not fatal: it is listed by `entry_point_problems` (and `fleet robots`), the rest work.
"""

from __future__ import annotations

import copyreg
import dataclasses
from importlib import metadata
from pathlib import Path

from robots.robot_file import RobotFileError, load_robot_file
from robots.spec import DriveGains, RobotSpec

_REGISTRY: dict[str, RobotSpec] = {}
_ENTRY_POINT_PROBLEMS: list[str] = []
_entry_points_loaded = False
ENTRY_POINT_GROUP = "clawfleet.robots"
MODELS_EXTRA_HINT = "pip install 'clawfleet[models]'"


class UnknownRobotError(KeyError):
    """Asked for a robot uid that is not registered; the message lists the valid ones."""

    def __str__(self) -> str:  # KeyError quotes its message; this reads as a sentence
        return str(self.args[0])


class MissingModelsError(RuntimeError):
    """The robot's description ships with an optional extra that is not installed."""


def register(spec: RobotSpec) -> RobotSpec:
    """Add a robot declaration under its uid (a second one with the same uid is an error)."""
    if spec.uid in _REGISTRY:
        raise ValueError(f"robot {spec.uid!r} is registered already")
    _REGISTRY[spec.uid] = spec
    return spec


def register_file(path: str | Path) -> RobotSpec:
    """Register the robot a YAML file declares (again for the same file: the same robot; raises `RobotFileError`)."""
    resolved = str(Path(path).expanduser().resolve())
    for spec in _REGISTRY.values():
        if spec.declared_in == resolved:
            return spec
    spec = load_robot_file(Path(path))
    _load_entry_points()
    if spec.uid in _REGISTRY:
        raise RobotFileError(resolved, "uid", f"{spec.uid!r} is taken (declared in {_REGISTRY[spec.uid].declared_in})")
    return register(spec)


def _entry_point_spec(entry: metadata.EntryPoint) -> RobotSpec:
    """The robot an entry point names: a spec, a function returning one, or a robot file's path."""
    target = entry.load()
    if callable(target) and not isinstance(target, RobotSpec):
        target = target()
    if isinstance(target, (str, Path)):
        return load_robot_file(Path(target))
    if not isinstance(target, RobotSpec):
        raise TypeError(
            f"names a {type(target).__name__}, not a RobotSpec, a function returning one or a robot file path"
        )
    return target


def _load_entry_points() -> None:
    """Register every robot of the `clawfleet.robots` group, once; problems are kept, not raised."""
    global _entry_points_loaded
    if _entry_points_loaded:
        return
    _entry_points_loaded = True
    for entry in metadata.entry_points(group=ENTRY_POINT_GROUP):
        dist = entry.dist.name if entry.dist is not None else "?"
        where = f"entry point {entry.name!r} of {dist}"
        try:
            spec = _entry_point_spec(entry)
            if spec.uid in _REGISTRY:
                raise ValueError(f"robot {spec.uid!r} is taken (declared in {_REGISTRY[spec.uid].declared_in})")
            register(dataclasses.replace(spec, declared_in=where) if spec.declared_in == "clawfleet" else spec)
        except Exception as exc:  # another package's code: whatever it raises is reported, never fatal
            _ENTRY_POINT_PROBLEMS.append(f"{where} ({entry.value}): {type(exc).__name__}: {exc}")


def entry_point_problems() -> list[str]:
    """One line per `clawfleet.robots` entry point that could not be loaded."""
    _load_entry_points()
    return list(_ENTRY_POINT_PROBLEMS)


def robot_names() -> list[str]:
    _load_entry_points()
    return sorted(_REGISTRY)


def declared_robots() -> list[RobotSpec]:
    """Every registered declaration, installed or not, by uid."""
    return [_REGISTRY[uid] for uid in robot_names()]


def get_robot(uid: str) -> RobotSpec:
    """The declaration of `uid`; raises with the valid names, or with the extra to install."""
    _load_entry_points()
    try:
        spec = _REGISTRY[uid]
    except KeyError:
        raise UnknownRobotError(f"unknown robot {uid!r}; valid robots: {', '.join(robot_names())}") from None
    spec.urdf_path()  # fails early, naming the extra, when the description is not installed
    return spec


def is_available(uid: str) -> bool:
    """True when the robot's description files are installed."""
    try:
        get_robot(uid)
    except MissingModelsError:
        return False
    return True


def _openclaw_urdf() -> Path:
    return Path(__file__).parent / "descriptions" / "openclaw.urdf"


def _example_robot_data(relative: str) -> Path:
    """A file of example-robot-data, or an error naming the extra that installs it."""
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        raise MissingModelsError(f"this robot needs example-robot-data: {MODELS_EXTRA_HINT}") from None
    path = Path(str(dist.locate_file(f"cmeel.prefix/share/example-robot-data/robots/{relative}")))
    if not path.is_file():
        raise MissingModelsError(f"example-robot-data is installed but lacks {relative}: {MODELS_EXTRA_HINT}")
    return path


OPENCLAW = register(
    RobotSpec(
        uid="openclaw",
        summary="clawfleet's own 6-DoF claw arm with a parallel two-finger claw; primitive collision shapes",
        urdf_path=_openclaw_urdf,
        arm_joints=("shoulder_pan", "shoulder_lift", "elbow", "forearm_roll", "wrist_pitch", "wrist_roll"),
        gripper_joints=("finger_left", "finger_right"),
        tool_frame="tool_link",
        home_q=(0.0, -0.2, 1.9, 0.0, 1.44, 0.0),
        gripper_open=(0.035, 0.035),
        gripper_closed=(0.002, 0.002),
        grasp_width_m=(0.02, 0.06),
        arm_gains=DriveGains(stiffness=2000.0, damping=120.0, force_limit=60.0),
        gripper_gains=DriveGains(stiffness=1500.0, damping=40.0, force_limit=25.0),
        finger_links=("finger_left_link", "finger_right_link"),
        finger_friction=1.5,
        width_per_gripper_unit_m=2.0,
        fingertip_below_tool_m=0.03,
        keyframes={"upright": (0.0,) * 6},
    )
)

SO101 = register(
    RobotSpec(
        uid="so101",
        summary="SO-101, the open 3D-printed 5-DoF arm with a jaw gripper (example-robot-data)",
        urdf_path=lambda: _example_robot_data("so_arm_description/urdf/so101.urdf"),
        arm_joints=("shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll"),
        gripper_joints=("gripper",),
        tool_frame="gripper_frame_link",
        home_q=(0.0, -0.5, 0.5, 1.2, 0.0),
        gripper_open=(1.2,),
        gripper_closed=(-0.15,),
        grasp_width_m=(0.015, 0.05),
        arm_gains=DriveGains(stiffness=800.0, damping=40.0, force_limit=10.0),  # by `fleet tune`
        gripper_gains=DriveGains(stiffness=50.0, damping=2.0, force_limit=3.0),
        finger_links=("gripper_link", "moving_jaw_so101_v1_link"),
        finger_friction=1.5,  # by `fleet tune`, with the fixed jaw's gap below (docs/benchmarks.md)
        closing_axis_tool=(1.0, 0.0, 0.0),  # the moving jaw swings towards the fixed one along the tool's x
        fixed_jaw_face_m=0.001,  # the tool frame sits at the fixed jaw's tip (measured on the collision shapes)
        carry_tilted=True,
        max_approach_tilt_deg=60.0,  # 5 joints, a short reach: it cannot point straight down over a belt
        # a short arm: low hovers keep the claw within its reach; speeds and lift by `fleet tune` (docs/benchmarks.md)
        pick_timing={
            "hover_m": 0.04,
            "lift_m": 0.06,
            "approach_speed": 0.6,
            "transfer_speed": 0.15,
            "lift_s": 0.8,
            "fixed_jaw_gap_m": 0.004,  # the fixed jaw comes down clear of the part: a grazed part tips out
        },  # fleet tune's best
        package_prefix="package://example-robot-data/robots/",
        needs_extra="models",
    )
)

PANDA = register(
    RobotSpec(
        uid="panda",
        summary="Franka Emika Panda, 7-DoF with a parallel gripper (example-robot-data)",
        urdf_path=lambda: _example_robot_data("panda_description/urdf/panda.urdf"),
        arm_joints=tuple(f"panda_joint{i}" for i in range(1, 8)),
        gripper_joints=("panda_finger_joint1", "panda_finger_joint2"),
        tool_frame="panda_hand_tcp",
        home_q=(0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.785),
        gripper_open=(0.04, 0.04),
        gripper_closed=(0.0, 0.0),
        grasp_width_m=(0.01, 0.08),
        arm_gains=DriveGains(stiffness=3000.0, damping=200.0, force_limit=87.0),
        gripper_gains=DriveGains(stiffness=2000.0, damping=60.0, force_limit=40.0),
        finger_links=("panda_leftfinger", "panda_rightfinger"),
        width_per_gripper_unit_m=2.0,
        package_prefix="package://example-robot-data/robots/",
        needs_extra="models",
    )
)


def _pickled_spec(spec: RobotSpec) -> tuple:
    """A registered declaration pickles as its name (a run's snapshot holds many; every process of the run has the
    registry, and a built-in's URDF is found by a function, which does not pickle); a variant of one whole."""
    if _REGISTRY.get(spec.uid) is spec:
        return (get_robot, (spec.uid,))
    return spec.__reduce_ex__(2)


copyreg.pickle(RobotSpec, _pickled_spec)
