"""A render-only copy of a physics world: one visual body per physics body, shaped by its collision shapes.

The physics world has no render system (it pays nothing for cameras); the
mirror builds its own scene from the world's collision shapes, so an image
shows exactly what the physics holds, and copies the moving bodies' poses in
before each render (`sync`, about 0.2 ms for a 4-arm line).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import sapien

from fleet.sim.cameras import labels
from fleet.sim.render import casts_shadows
from fleet.sim.world import World

SHADOW_MAP_PX = (128, 512)  # the shadow map's size, fitted to the largest camera within these: SAPIEN draws the
# map again for every camera's frame, and 2048 (its default) costs a small frame 5x its render on a CPU
FLOOR_RGB = (0.78, 0.78, 0.76)
STATION_RGB = {"bin": (0.55, 0.42, 0.28), "fixture": (0.45, 0.5, 0.58), "tray": (0.4, 0.52, 0.4)}
MESH_SHAPES = (sapien.physx.PhysxCollisionShapeConvexMesh, sapien.physx.PhysxCollisionShapeTriangleMesh)
ARM_RGB = [(0.93, 0.55, 0.18), (0.85, 0.85, 0.88), (0.95, 0.8, 0.25), (0.6, 0.75, 0.9)]  # taken in turn by arm index


@dataclass
class Twin:
    """A physics body and its visual copy, with the segmentation id it renders as (parts: set each sync)."""

    body: sapien.Entity
    visual: sapien.Entity
    label: int
    moves: bool
    shown: bool = True


def _material(rgb: tuple[float, float, float]) -> sapien.render.RenderMaterial:
    return sapien.render.RenderMaterial(base_color=[*rgb, 1.0], roughness=0.7, metallic=0.0)


def _mesh_visual(shape, material: sapien.render.RenderMaterial) -> sapien.render.RenderShapeTriangleMesh:
    """A flat-shaded copy of a convex or triangle mesh collision shape."""
    vertices = np.asarray(shape.get_vertices(), np.float32) * np.asarray(shape.get_scale(), np.float32)
    corners = vertices[np.asarray(shape.get_triangles(), np.int64)]  # (triangles, 3, 3)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    flat = corners.reshape(-1, 3)
    return sapien.render.RenderShapeTriangleMesh(
        flat,
        np.arange(len(flat), dtype=np.uint32).reshape(-1, 3),
        np.repeat(normals, 3, axis=0).astype(np.float32),
        np.zeros((len(flat), 2), np.float32),
        material,
    )


def _unit_scale(shape) -> np.ndarray:
    """What SAPIEN scales a shape's stored vertices by when it draws it (its primitives are stored unit-sized)."""
    if isinstance(shape, sapien.render.RenderShapeBox):
        return np.asarray(shape.half_size, np.float32)
    if isinstance(shape, sapien.render.RenderShapeCylinder):
        return np.asarray([shape.half_length, shape.radius, shape.radius], np.float32)
    if isinstance(shape, sapien.render.RenderShapeSphere):
        return np.full(3, shape.radius, np.float32)
    if isinstance(shape, sapien.render.RenderShapeTriangleMesh):
        return np.asarray(shape.scale, np.float32)
    return np.ones(3, np.float32)  # a capsule is stored at its size


def merged_visual(shapes: list) -> sapien.render.RenderShapeTriangleMesh:
    """`shapes` of one body as one mesh in the body's frame: one draw call where there were several (a draw costs
    about 28 us a pass on a CPU renderer, and each camera draws every body twice with shadows on)."""
    vertices, triangles, normals = [], [], []
    count = 0
    for shape in shapes:
        rotation = shape.local_pose.to_transformation_matrix()[:3, :3]
        scale = _unit_scale(shape)
        for part in shape.parts:
            local = np.asarray(part.get_vertices(), np.float32) * scale
            vertices.append(local @ rotation.T + shape.local_pose.p)
            normal = np.asarray(part.get_vertex_normal(), np.float32) / scale
            normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
            normals.append(normal @ rotation.T)
            triangles.append(np.asarray(part.get_triangles(), np.uint32) + count)
            count += len(local)
    flat = np.concatenate(vertices).astype(np.float32)
    return sapien.render.RenderShapeTriangleMesh(
        flat,
        np.concatenate(triangles),
        np.concatenate(normals).astype(np.float32),
        np.zeros((len(flat), 2), np.float32),
        shapes[0].material,
    )


def visual_shapes(body: sapien.Entity, rgb: tuple[float, float, float]) -> list:
    """One render shape per collision shape of `body`, at the same local pose."""
    material = _material(rgb)
    shapes = []
    for component in body.components:
        if not isinstance(component, sapien.physx.PhysxRigidBaseComponent):
            continue
        for s in component.get_collision_shapes():
            if isinstance(s, sapien.physx.PhysxCollisionShapeBox):
                v = sapien.render.RenderShapeBox(s.half_size, material)
            elif isinstance(s, sapien.physx.PhysxCollisionShapeCylinder):
                v = sapien.render.RenderShapeCylinder(s.radius, s.half_length, material)
            elif isinstance(s, sapien.physx.PhysxCollisionShapeCapsule):
                v = sapien.render.RenderShapeCapsule(s.radius, s.half_length, material)
            elif isinstance(s, sapien.physx.PhysxCollisionShapeSphere):
                v = sapien.render.RenderShapeSphere(s.radius, material)
            elif isinstance(s, MESH_SHAPES):
                v = _mesh_visual(s, material)
            else:  # a plane: nothing a camera needs
                continue
            v.local_pose = s.local_pose
            shapes.append(v)
    return shapes


def shadow_map_px(largest_camera_px: int) -> int:
    """The shadow map's side for cameras at most `largest_camera_px` wide or high: twice that, a power of two, within
    `SHADOW_MAP_PX` (a 64 px wrist camera needs no 512 px map, and each camera's frame draws the map again)."""
    low, high = SHADOW_MAP_PX
    return int(min(high, max(low, 2 ** math.ceil(math.log2(max(1, 2 * largest_camera_px))))))


class RenderMirror:
    """The world's bodies in a render scene of their own, lit; `sync` copies the moving ones' poses in."""

    def __init__(
        self, world: World, render_system: sapien.render.RenderSystem, largest_camera_px: int = SHADOW_MAP_PX[1]
    ) -> None:
        self.world = world
        self.scene = sapien.Scene([render_system])
        self._light(shadow_map_px(largest_camera_px))
        self.twins: list[Twin] = []
        self._part_twins: list[tuple[Twin, int]] = []  # (twin, pool slot)
        self._build()

    def _light(self, shadow_px: int) -> None:
        """The scene's lighting; a shadow map just wide enough for the cell's bodies."""
        light = self.world.scene_model.appearance
        self.scene.set_ambient_light([light.ambient] * 3)
        reach_m = max(
            (float(np.abs(e.pose.p[:2]).max()) for e in self.world.scene.entities if e.pose.p[2] > -1), default=1
        )
        self.scene.add_directional_light(
            list(light.light_direction_xyz),
            [light.light_intensity] * 3,
            shadow=casts_shadows(light.shadows),
            shadow_scale=min(reach_m + 1.5, 30.0),
            shadow_map_size=shadow_px,
        )

    def _build(self) -> None:
        model = self.world.scene_model
        looks = model.appearance
        stations = {s.name: i for i, s in enumerate(model.stations)}
        slots = {p.entity.per_scene_id: p for p in self.world.parts}  # wrappers differ per access; ids do not
        links = {}
        for a, arm in enumerate(self.world.arms.values()):
            for j, link in enumerate(arm.articulation.get_links()):
                links[link.entity.per_scene_id] = (labels.arm_link_label(a, j), ARM_RGB[a % len(ARM_RGB)])
        for body in self.world.scene.entities:
            key = body.per_scene_id
            if key in slots:
                part = slots[key]
                shade = tuple(min(1.0, c * looks.part_shade) for c in part.part_type.rgb)
                twin = self._add(body, shade, labels.NOTHING, moves=True)
                self._part_twins.append((twin, part.slot))
            elif key in links:
                self._add(body, links[key][1], links[key][0], moves=True)
            elif body.name in stations:
                station = model.stations[stations[body.name]]
                self._add(body, STATION_RGB[station.kind], labels.station_label(stations[body.name]), moves=False)
            elif body.name == "conveyor_belt":  # a box whose surface moves, not its pose
                self._add(body, (looks.belt_grey,) * 3, labels.BELT, moves=False)
            elif body.name == "floor":
                self._add(body, FLOOR_RGB, labels.FLOOR, moves=False)

    def _add(self, body: sapien.Entity, rgb: tuple[float, float, float], label: int, moves: bool) -> Twin:
        render_body = sapien.render.RenderBodyComponent()
        shapes = visual_shapes(body, rgb)
        if shapes:
            render_body.attach(merged_visual(shapes) if len(shapes) > 1 else shapes[0])
        visual = sapien.Entity()
        visual.name = body.name
        visual.add_component(render_body)
        self.scene.add_entity(visual)
        visual.set_pose(body.pose)
        twin = Twin(body, visual, label, moves)
        self.twins.append(twin)
        return twin

    def use_world(self, world: World) -> None:
        """Copy `world` from now on: a world of the same scene built afresh (a line goes on in one after each
        snapshot), whose bodies stand in the same order as this one's."""
        index = {body.per_scene_id: i for i, body in enumerate(self.world.scene.entities)}
        bodies = world.scene.entities
        for twin in self.twins:
            twin.body = bodies[index[twin.body.per_scene_id]]
        self.world = world

    def sync(self) -> None:
        """Copy the moving bodies' poses, and which part each pooled body is now, from the world."""
        for twin in self.twins:
            if twin.moves:
                twin.visual.set_pose(twin.body.pose)
        for twin, slot in self._part_twins:
            part_id = self.world.parts[slot].part_id
            twin.label = labels.NOTHING if part_id is None else labels.part_label(part_id)
            if twin.shown != (part_id is not None):  # a parked part is not in the render scene at all: a body
                # only disabled still costs its draws in the shadow pass
                twin.shown = part_id is not None
                self.scene.add_entity(twin.visual) if twin.shown else self.scene.remove_entity(twin.visual)

    def label_table(self) -> np.ndarray:
        """Render id (a visual body's id in this scene) -> segmentation id, as a lookup array (after `sync`)."""
        drawn = [t for t in self.twins if t.shown]  # a body added again has a new render id
        table = np.zeros(max((t.visual.per_scene_id for t in drawn), default=0) + 1, np.int32)
        for twin in drawn:
            table[twin.visual.per_scene_id] = twin.label
        return table
