"""The 3D cell on the page: belt, stations, arms from their URDF visuals, parts, labels, separations.

Static solids come from `scenes.shapes` (the same boxes the physics collides with);
each arm is Viser's URDF helper over the robot's own URDF, posed from `ArmState`.
Names in the scene tree carry the arm id: `/arms/arm_0`, `/arms/arm_0/label`.
"""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import viser
from viser.extras import ViserUrdf

from fleet.bus.messages import ArmState
from fleet.monitor.feed import LineSight
from robots.phase import Phase
from robots.registry import get_robot
from robots.spec import RobotSpec
from scenes.schema import Scene, Station
from scenes.shapes import belt_box, station_boxes

STATION_RGB = {"fixture": (150, 150, 160), "bin": (110, 130, 165), "tray": (90, 150, 90)}  # none orange like the arms
BELT_RGB = (60, 60, 66)
ARM_RGB = [(230, 90, 60), (60, 160, 230), (120, 200, 80), (200, 120, 220), (240, 190, 60), (80, 200, 190)]
NEAR_RGB, SAFE_RGB, CLOSE_RGB = (230, 30, 30), (40, 180, 80), (240, 160, 30)
CONTACT_FLAG_S = 2.0  # sim seconds a contact stays flagged on the page


def yaw_wxyz(yaw_rad: float) -> tuple[float, float, float, float]:
    return (math.cos(yaw_rad / 2), 0.0, 0.0, math.sin(yaw_rad / 2))


def hex_rgb(colour: str) -> tuple[int, int, int]:
    h = colour.lstrip("#")
    return tuple(int(h[i : i + 2], 16) for i in (0, 2, 4))  # type: ignore[return-value]


def arm_colour(index: int) -> tuple[int, int, int]:
    return ARM_RGB[index % len(ARM_RGB)]


class ArmModel:
    """One arm drawn from its URDF's visual geometry, under `/arms/<id>` placed at its base."""

    def __init__(
        self,
        server: viser.ViserServer,
        name: str,
        spec: RobotSpec,
        xyz: tuple[float, float, float],
        yaw_rad: float,
        rgb: tuple[int, int, int],
    ) -> None:
        import yourdfpy

        self.name, self.spec = name, spec
        self.root = server.scene.add_frame(f"/arms/{name}", show_axes=False, position=xyz, wxyz=yaw_wxyz(yaw_rad))
        with tempfile.TemporaryDirectory() as tmp:  # the resolved URDF (absolute mesh paths, no mimic tags)
            path = Path(tmp) / f"{spec.uid}.urdf"
            path.write_text(spec.urdf_text())
            urdf = yourdfpy.URDF.load(str(path), build_scene_graph=True, load_meshes=True)
        self.urdf = ViserUrdf(server, urdf, root_node_name=f"/arms/{name}")
        joints = {j: i for i, j in enumerate((*spec.arm_joints, *spec.gripper_joints))}
        self._order = [joints[j] for j in self.urdf.get_actuated_joint_names()]
        # labels sit at the root of the scene tree: Viser does not draw a label parented to a frame
        self.label = server.scene.add_label(
            f"/labels/{name}",
            name,
            position=(xyz[0], xyz[1], xyz[2] + 0.6),
            anchor="bottom-center",
            font_screen_scale=1.2,
        )
        self.ring = server.scene.add_cylinder(
            f"/arms/{name}/ring", radius=0.09, height=0.004, color=rgb, position=(0.0, 0.0, 0.002)
        )
        self._last_q: tuple[float, ...] | None = None
        self.update_cfg(np.asarray(spec.home_q), np.asarray(spec.gripper_open))

    def update_cfg(self, q: np.ndarray, gripper_q: np.ndarray) -> None:
        full = np.concatenate([q, gripper_q])
        key = tuple(np.round(full, 4))
        if key != self._last_q:  # an arm at rest costs no messages
            self._last_q = key
            self.urdf.update_cfg(full[self._order])

    def show(self, state: ArmState) -> None:
        self.update_cfg(np.asarray(state.q), np.asarray(state.gripper_q))
        what = "LOST" if state.lost else ("held" if state.held else state.phase)
        task = f" · task {state.task_id}" if state.task_id is not None and state.phase != Phase.IDLE else ""
        text = f"{self.name} · {what}{task}"
        if self.label.text != text:
            self.label.text = text


class CellView:
    """Everything drawn in the 3D scene; `show(sight)` brings it up to date."""

    def __init__(self, server: viser.ViserServer, scene: Scene) -> None:
        self.server, self.scene = server, scene
        server.scene.set_up_direction("+z")
        server.scene.add_grid(
            "/ground", width=4.0, height=4.0, cell_size=0.1, section_size=0.5, position=(0.0, -0.3, 0.0)
        )
        self._draw_static()
        self._aim_camera()
        self.arm_index = {a.name: i for i, a in enumerate(scene.arms)}
        self.arms = {
            a.name: ArmModel(server, a.name, get_robot(a.model), a.base.xyz, a.base.yaw_rad, arm_colour(i))
            for i, a in enumerate(scene.arms)
        }
        self.part_types = {f.name: f.parts for f in scene.feeders}
        self.parts: dict[int, viser.SceneNodeHandle] = {}
        self.highlights: dict[int, viser.SceneNodeHandle] = {}
        self.separation_lines: viser.SceneNodeHandle | None = None
        self.contact_label = server.scene.add_label(
            "/labels/contact",
            "",
            position=(0.0, -0.3, 0.8),
            visible=False,
            anchor="bottom-center",
            font_screen_scale=1.5,
        )

    def _aim_camera(self) -> None:
        """Look at the middle of the cell from the front, far enough to see every arm."""
        points = [a.base.xyz for a in self.scene.arms] + [s.pose.xyz for s in self.scene.stations]
        if self.scene.conveyor is not None:
            c = self.scene.conveyor
            points += [c.point_at(0.0), c.point_at(c.length_m)]
        xyz = np.asarray(points, float)
        centre = (xyz.min(axis=0) + xyz.max(axis=0)) / 2
        span = float(np.max(xyz.max(axis=0)[:2] - xyz.min(axis=0)[:2])) + 0.6
        camera = self.server.initial_camera
        camera.look_at = (float(centre[0]), float(centre[1]), 0.1)
        camera.position = (float(centre[0]) + 0.2 * span, float(centre[1]) - 0.8 * span, 0.6 * span)

    def _draw_static(self) -> None:
        c = self.scene.conveyor
        if c is not None:
            frame = self.server.scene.add_frame(
                "/conveyor", show_axes=False, position=c.pose.xyz, wxyz=yaw_wxyz(c.pose.yaw_rad)
            )
            centre, half = belt_box(c)
            self.server.scene.add_box(
                f"{frame.name}/belt", color=BELT_RGB, dimensions=tuple(2 * h for h in half), position=centre
            )
        for s in self.scene.stations:
            self._draw_station(s)

    def _draw_station(self, s: Station) -> None:
        frame = self.server.scene.add_frame(
            f"/stations/{s.name}", show_axes=False, position=s.pose.xyz, wxyz=yaw_wxyz(s.pose.yaw_rad)
        )
        rgb = STATION_RGB[s.kind]
        for i, (centre, half) in enumerate(station_boxes(s)):
            self.server.scene.add_box(
                f"{frame.name}/box_{i}", color=rgb, dimensions=tuple(2 * h for h in half), position=centre
            )
        x, y, z = s.pose.xyz
        self.server.scene.add_label(
            f"/labels/{s.name}",
            s.name,
            position=(x, y, z + s.size_m[2] + 0.03),
            anchor="bottom-center",
            font_screen_scale=0.8,
        )

    # --- live ---------------------------------------------------------------------
    def show(self, snap: LineSight) -> None:
        for name, state in snap.arms.items():
            if name in self.arms:
                self.arms[name].show(state)
        self._show_parts(snap)
        self._show_separations(snap)
        self._show_contact(snap)

    def _part_handle(self, part_id: int, feeder: str, type_index: int) -> viser.SceneNodeHandle:
        kinds = self.part_types.get(feeder)
        part = kinds[min(type_index, len(kinds) - 1)] if kinds else None
        rgb = hex_rgb(part.colour) if part else (200, 200, 200)
        size = part.size_m if part else (0.04, 0.04, 0.04)
        name = f"/parts/{part_id}"
        if part is not None and part.kind == "cylinder":
            return self.server.scene.add_cylinder(name, radius=size[0] / 2, height=size[2], color=rgb)
        return self.server.scene.add_box(name, color=rgb, dimensions=size)

    def _show_parts(self, snap: LineSight) -> None:
        p = snap.parts
        if p is None:
            return
        seen = set()
        for i, pid in enumerate(p.part_ids):
            seen.add(pid)
            handle = self.parts.get(pid)
            if handle is None:
                handle = self.parts[pid] = self._part_handle(pid, p.feeders[i], p.type_indices[i])
            handle.position = p.positions[3 * i : 3 * i + 3]
            handle.wxyz = p.quaternions_wxyz[4 * i : 4 * i + 4]
        for pid in [pid for pid in self.parts if pid not in seen]:
            self.parts.pop(pid).remove()
        self._show_assigned(snap, seen)

    def _show_assigned(self, snap: LineSight, active: set[int]) -> None:
        """A wireframe cage in the arm's colour around each part an arm is working on."""
        wanted = {}
        for arm, a in snap.assignments.items():
            state = snap.arms.get(arm)
            if a.task_id is not None and a.part_id in active and state is not None and state.task_id == a.task_id:
                wanted[a.part_id] = arm
        for pid in [pid for pid in self.highlights if pid not in wanted]:
            self.highlights.pop(pid).remove()
        for pid, arm in wanted.items():
            if pid not in self.highlights:
                self.highlights[pid] = self.server.scene.add_box(
                    f"/parts/{pid}/assigned",
                    color=arm_colour(self.arm_index.get(arm, 0)),
                    dimensions=(0.08, 0.08, 0.08),
                    wireframe=True,
                )

    def _show_separations(self, snap: LineSight) -> None:
        """A line between the closest points of each arm and its nearest neighbour: red below the guard's margin."""
        s = snap.separations
        if s is None or not s.distances_m:
            return
        points = np.asarray(s.points, np.float32).reshape(-1, 2, 3)
        colours = np.array(
            [NEAR_RGB if d < s.margin_m else (CLOSE_RGB if d < 3 * s.margin_m else SAFE_RGB) for d in s.distances_m],
            np.uint8,
        )[:, None, :].repeat(2, axis=1)
        if self.separation_lines is None:
            self.separation_lines = self.server.scene.add_line_segments(
                "/separations", points, colours, thickness=4.0, thickness_units="screen"
            )
        else:
            self.separation_lines.points, self.separation_lines.colors = points, colours

    def _show_contact(self, snap: LineSight) -> None:
        st = snap.status
        recent = st is not None and st.last_contact_s >= 0 and snap.sim_time_s - st.last_contact_s < CONTACT_FLAG_S
        if recent:
            text = "CONTACT " + ", ".join(st.contact_pairs)
            if self.contact_label.text != text:
                self.contact_label.text = text
        if self.contact_label.visible != recent:
            self.contact_label.visible = recent
