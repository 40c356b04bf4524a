"""The line as ROS 2 tools expect it: TF for every link (as robot_state_publisher would), joint states, markers.

Frames: `world` is the root; each arm's links are `<arm>/<link>` (the URDF's link names under the arm id, as a
tf_prefix would), its root link placed on `world` by `/tf_static`; each joint's child link is published on
`/tf` relative to its parent link, from Pinocchio's forward kinematics of the arm's own URDF. The belt and
stations are markers in `world` on `/cell`; parts on `/parts` (each message replaces the last: DELETEALL first).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cache

import numpy as np
import pinocchio as pin

from fleet.bus.messages import ArmState, PartsState
from fleet.record.camera_to_ros import camera_static_transforms
from fleet.record.ros_types import ros_type, time_msg
from robots.frames import yaw_transform
from robots.kinematics import KinematicModel
from robots.registry import get_robot
from scenes.schema import Scene
from scenes.shapes import belt_box, station_boxes

WORLD = "world"
BELT_RGBA = (0.24, 0.24, 0.26, 1.0)
STATION_RGBA = {"fixture": (0.59, 0.59, 0.63, 1.0), "bin": (0.43, 0.51, 0.65, 1.0), "tray": (0.35, 0.59, 0.35, 1.0)}


def _header(sim_time_s: float, frame_id: str, stamp: object | None = None):
    """A header in `frame_id`; `stamp` (a `builtin_interfaces/Time`) shared by the messages of one tick, else made."""
    return ros_type("std_msgs/msg/Header")(
        stamp=stamp if stamp is not None else time_msg(sim_time_s), frame_id=frame_id
    )


Vector3, Quaternion = ros_type("geometry_msgs/msg/Vector3"), ros_type("geometry_msgs/msg/Quaternion")
Transform, TransformStamped = ros_type("geometry_msgs/msg/Transform"), ros_type("geometry_msgs/msg/TransformStamped")


def _transform_msg(pose: pin.SE3 | np.ndarray):
    """`geometry_msgs/Transform` of a pose (SE3 or 4x4 matrix); Pinocchio's XYZQUAT is x, y, z, qx, qy, qz, qw, as
    ROS."""
    x, y, z, qx, qy, qz, qw = pin.SE3ToXYZQUAT(pose if isinstance(pose, pin.SE3) else pin.SE3(pose)).tolist()
    return Transform(translation=Vector3(x=x, y=y, z=z), rotation=Quaternion(x=qx, y=qy, z=qz, w=qw))


def _stamped(sim_time_s: float, parent: str, child: str, pose: pin.SE3 | np.ndarray, stamp: object | None = None):
    return TransformStamped(
        header=_header(sim_time_s, parent, stamp), child_frame_id=child, transform=_transform_msg(pose)
    )


@dataclass(frozen=True)
class _Link:
    """A link with a parent link: its Pinocchio frame index and its parent's."""

    name: str
    frame: int
    parent: str
    parent_frame: int


class ArmTf:
    """One arm's links as TF frames and its joints as `sensor_msgs/JointState`, from its `ArmState`s."""

    def __init__(self, arm: str, model_uid: str, xyz: tuple[float, float, float], yaw_rad: float) -> None:
        self.arm = arm
        self.spec = get_robot(model_uid)
        self.kin = KinematicModel(self.spec)
        self.joint_names = [*self.spec.arm_joints, *self.spec.gripper_joints]
        self.base_to_world = yaw_transform(xyz, yaw_rad)
        frames = self.kin.model.frames
        bodies = [i for i, f in enumerate(frames) if f.type == pin.FrameType.BODY]
        self.root_link = frames[bodies[0]].name
        self.links = [self._link(i) for i in bodies[1:]]
        moves = [frames[link.frame].parentJoint != frames[link.parent_frame].parentJoint for link in self.links]
        self.fixed_links = [link for link, moving in zip(self.links, moves) if not moving]  # on /tf_static
        self._named_links = [
            (link, self.frame(link.parent), self.frame(link.name)) for link, moving in zip(self.links, moves) if moving
        ]

    def _link(self, index: int) -> _Link:
        frames = self.kin.model.frames
        parent = frames[index].parentFrame
        while frames[parent].type != pin.FrameType.BODY:  # through the joint (and fixed-joint) frames
            parent = frames[parent].parentFrame
        return _Link(frames[index].name, index, frames[parent].name, parent)

    def frame(self, link: str) -> str:
        return f"{self.arm}/{link}"

    def static_transforms(self, sim_time_s: float = 0.0) -> list:
        """The arm's root link on `world`, and every link fixed to its parent (as robot_state_publisher: fixed joints
        go on `/tf_static`, moving ones on `/tf`)."""
        model, data = self.kin.model, self.kin.data
        pin.framesForwardKinematics(model, data, pin.neutral(model))
        return [_stamped(sim_time_s, WORLD, self.frame(self.root_link), self.base_to_world)] + [
            _stamped(
                sim_time_s,
                self.frame(link.parent),
                self.frame(link.name),
                data.oMf[link.parent_frame].actInv(data.oMf[link.frame]),
            )
            for link in self.fixed_links
        ]

    def transforms(self, state: ArmState, stamp: object | None = None) -> list:
        """Every link that moves relative to its parent link at this state (`stamp`: the tick's shared Time)."""
        model, data = self.kin.model, self.kin.data
        pin.framesForwardKinematics(model, data, self.kin.full_q(np.asarray(state.q), np.asarray(state.gripper_q)))
        stamp = stamp if stamp is not None else time_msg(state.sim_time_s)
        oMf = data.oMf
        return [
            _stamped(state.sim_time_s, parent, child, oMf[link.parent_frame].actInv(oMf[link.frame]), stamp)
            for link, parent, child in self._named_links
        ]

    def joint_state(self, state: ArmState):
        """Positions of every joint by its URDF name; velocities of the arm joints (the claw's are not measured:
        NaN)."""
        position = np.asarray((*state.q, *state.gripper_q), dtype=np.float64)
        velocity = np.asarray((*state.dq, *([math.nan] * len(state.gripper_q))), dtype=np.float64)
        return ros_type("sensor_msgs/msg/JointState")(
            header=_header(state.sim_time_s, ""),
            name=list(self.joint_names),
            position=position,
            velocity=velocity,
            effort=np.zeros(0, dtype=np.float64),
        )


@cache
def _unused_marker_fields() -> dict:
    """The fields a plain shape marker leaves empty (no lifetime, texture or mesh); made once, shared by every marker
    (messages are only read, when serialised)."""
    return dict(
        lifetime=ros_type("builtin_interfaces/msg/Duration")(sec=0, nanosec=0),
        frame_locked=False,
        points=[],
        colors=[],
        texture_resource="",
        texture=ros_type("sensor_msgs/msg/CompressedImage")(
            header=_header(0.0, ""), format="", data=np.zeros(0, np.uint8)
        ),
        uv_coordinates=[],
        text="",
        mesh_resource="",
        mesh_file=ros_type("visualization_msgs/msg/MeshFile")(filename="", data=np.zeros(0, np.uint8)),
        mesh_use_embedded_materials=False,
    )


def _marker(
    sim_time_s: float,
    ns: str,
    marker_id: int,
    kind: int,
    matrix: np.ndarray,
    scale: tuple,
    rgba: tuple,
    action: int = 0,
    stamp: object | None = None,
):
    """One `visualization_msgs/Marker` in `world` (no texture, no mesh, no lifetime: it stays until replaced)."""
    t = _transform_msg(matrix)
    pose = ros_type("geometry_msgs/msg/Pose")(
        position=ros_type("geometry_msgs/msg/Point")(x=t.translation.x, y=t.translation.y, z=t.translation.z),
        orientation=t.rotation,
    )
    return ros_type("visualization_msgs/msg/Marker")(
        header=_header(sim_time_s, WORLD, stamp),
        ns=ns,
        id=marker_id,
        type=kind,
        action=action,
        pose=pose,
        scale=ros_type("geometry_msgs/msg/Vector3")(x=float(scale[0]), y=float(scale[1]), z=float(scale[2])),
        color=ros_type("std_msgs/msg/ColorRGBA")(
            r=float(rgba[0]), g=float(rgba[1]), b=float(rgba[2]), a=float(rgba[3])
        ),
        **_unused_marker_fields(),
    )


def _translation(xyz) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = xyz
    return m


class LineToRos:
    """Builds the ROS messages of one scene's line: static TF and cell markers once, then per state and per parts
    message."""

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.arms = {a.name: ArmTf(a.name, a.model, a.base.xyz, a.base.yaw_rad) for a in scene.arms}
        self.part_rgba = {(f.name, i): (*p.rgb, 1.0) for f in scene.feeders for i, p in enumerate(f.parts)}
        self.part_kind = {(f.name, i): p.kind for f in scene.feeders for i, p in enumerate(f.parts)}
        marker = ros_type("visualization_msgs/msg/Marker")
        self.CUBE, self.CYLINDER, self.DELETEALL = marker.CUBE, marker.CYLINDER, marker.DELETEALL

    def tf_static(self):
        """Each arm's root on `world` and each camera's optical frame on its mount."""
        return ros_type("tf2_msgs/msg/TFMessage")(
            transforms=[t for arm in self.arms.values() for t in arm.static_transforms()]
            + camera_static_transforms(self.scene)
        )

    def tf(self, states: list[ArmState]):
        """Every moving link of the given arms (one tick of the line) in one message."""
        stamps: dict[float, object] = {}  # one Time object per sim time (a frame's arms share theirs)
        for s in states:
            if s.sim_time_s not in stamps:
                stamps[s.sim_time_s] = time_msg(s.sim_time_s)
        return ros_type("tf2_msgs/msg/TFMessage")(
            transforms=[t for s in states for t in self.arms[s.arm].transforms(s, stamps[s.sim_time_s])]
        )

    def joint_state(self, state: ArmState):
        return self.arms[state.arm].joint_state(state)

    def cell_markers(self):
        """The belt and every station's boxes (the same boxes the physics collides with)."""
        markers = []
        c = self.scene.conveyor
        if c is not None:
            centre, half = belt_box(c)
            markers.append(
                _marker(
                    0.0,
                    "belt",
                    0,
                    self.CUBE,
                    yaw_transform(c.pose.xyz, c.pose.yaw_rad) @ _translation(centre),
                    [2 * h for h in half],
                    BELT_RGBA,
                )
            )
        for s in self.scene.stations:
            place = yaw_transform(s.pose.xyz, s.pose.yaw_rad)
            for i, (centre, half) in enumerate(station_boxes(s)):
                markers.append(
                    _marker(
                        0.0,
                        f"stations/{s.name}",
                        i,
                        self.CUBE,
                        place @ _translation(centre),
                        [2 * h for h in half],
                        STATION_RGBA[s.kind],
                    )
                )
        return ros_type("visualization_msgs/msg/MarkerArray")(markers=markers)

    def parts_markers(self, parts: PartsState):
        """Every part on the line now, replacing those of the previous message."""
        t, stamp = parts.sim_time_s, time_msg(parts.sim_time_s)
        markers = [
            _marker(t, "parts", 0, self.CUBE, np.eye(4), (1, 1, 1), (0, 0, 0, 0), action=self.DELETEALL, stamp=stamp)
        ]
        for i, part_id in enumerate(parts.part_ids):
            key = (parts.feeders[i], parts.type_indices[i])
            pose = np.eye(4)
            pose[:3, :3] = pin.Quaternion(*parts.quaternions_wxyz[4 * i : 4 * i + 4]).toRotationMatrix()  # w, x, y, z
            pose[:3, 3] = parts.positions[3 * i : 3 * i + 3]
            kind = self.CYLINDER if self.part_kind.get(key) == "cylinder" else self.CUBE
            markers.append(
                _marker(
                    t,
                    "parts",
                    part_id,
                    kind,
                    pose,
                    parts.sizes_m[3 * i : 3 * i + 3],
                    self.part_rgba.get(key, (0.8, 0.8, 0.8, 1.0)),
                    stamp=stamp,
                )
            )
        return ros_type("visualization_msgs/msg/MarkerArray")(markers=markers)
