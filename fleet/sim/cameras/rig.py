"""The scene's cameras over a world: which are due at a tick, and their frames, all rendered in one pass."""

from __future__ import annotations

import math

import numpy as np
import sapien

from fleet.sim.cameras.frames import CameraFrame
from fleet.sim.cameras.mirror import RenderMirror
from fleet.sim.cameras.placement import body_pose, optical_pose
from fleet.sim.render import render_system
from fleet.sim.world import World
from perception.seen_ticks import frame_due
from scenes.schema import Camera


class CameraMountError(ValueError):
    """A camera mounted on a link its arm does not have."""


class MountedCamera:
    """One scene camera in the mirror: a SAPIEN camera placed in the world or riding on an arm link."""

    def __init__(self, camera: Camera, mirror: RenderMirror, world: World) -> None:
        self.model = camera
        self.local = body_pose(camera.pose)
        self.link = None
        if camera.arm is not None:
            links = {link.name: link for link in world.arms[camera.arm].articulation.get_links()}
            if camera.link not in links:
                raise CameraMountError(
                    f"camera {camera.name!r}: {camera.arm} has no link {camera.link!r}; links: {', '.join(links)}"
                )
            self.link = links[camera.link]
        self.sensor = mirror.scene.add_camera(
            camera.name, camera.width_px, camera.height_px, math.radians(camera.fov_deg), camera.near_m, camera.far_m
        )
        self.place()

    def use_world(self, world: World) -> None:
        """Ride on the same link of `world`'s arm (a world of the same scene built afresh)."""
        if self.link is not None:
            links = {link.name: link for link in world.arms[self.model.arm].articulation.get_links()}
            self.link = links[self.model.link]

    def place(self) -> sapien.Pose:
        """Move the camera to where its mount is now; its body's pose in the world."""
        pose = self.local if self.link is None else self.link.entity_pose * self.local
        self.sensor.entity.set_pose(pose)
        return pose

    def due(self, tick: int, control_hz: float) -> bool:
        """Whether a frame falls on this control tick (`perception.seen_ticks.frame_due`)."""
        return frame_due(tick, self.model.rate_hz, control_hz)


class CameraRig:
    """Every camera of a scene over one world: built once, then `frames(tick)` renders the cameras due then."""

    def __init__(self, world: World, cameras: list[Camera] | None = None) -> None:
        self.world = world
        chosen = world.scene_model.cameras if cameras is None else cameras
        largest_px = max((max(c.width_px, c.height_px) for c in chosen), default=1)
        self.mirror = RenderMirror(world, render_system(), largest_px)
        self.cameras = {c.name: MountedCamera(c, self.mirror, world) for c in chosen}

    def use_world(self, world: World) -> None:
        """Film `world` from now on (a world of the same scene built afresh, as a line goes on in after a snapshot):
        the render scene and its compiled pipelines are kept."""
        self.mirror.use_world(world)
        for camera in self.cameras.values():
            camera.use_world(world)
        self.world = world

    def due(self, tick: int | None = None) -> list[str]:
        """The cameras with a frame due at `tick` (default: the world's tick now)."""
        tick = self.world.tick if tick is None else tick
        return [n for n, c in self.cameras.items() if c.due(tick, self.world.scene_model.control_hz)]

    def frames(self, names: list[str] | None = None) -> dict[str, CameraFrame]:
        """Frames of `names` (default: every camera) from the world as it stands, rendered in one pass."""
        names = list(self.cameras) if names is None else names
        if not names:
            return {}
        self.mirror.sync()
        poses = {n: self.cameras[n].place() for n in names}
        self.mirror.scene.update_render()
        table = self.mirror.label_table()
        return {n: self._picture(self.cameras[n], poses[n], table) for n in names}

    def _picture(self, camera: MountedCamera, pose: sapien.Pose, table: np.ndarray) -> CameraFrame:
        sensor, made = camera.sensor, camera.model.images
        sensor.take_picture()
        rgb = depth = segmentation = None
        if "rgb" in made:
            colour = sensor.get_picture("Color")[..., :3]
            rgb = (np.clip(colour, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
        if "depth" in made or "segmentation" in made:
            # camera-space position in millimetres (OpenGL axes: -z forward; 0 where nothing was drawn) and the
            # visual body's id, from the one image SAPIEN's minimal shader writes both to
            position_ids = sensor.get_picture("PositionSegmentation")
            if "depth" in made:
                depth = (position_ids[..., 2].astype(np.float32) * np.float32(-0.001)).clip(min=0.0)
            if "segmentation" in made:
                ids = position_ids[..., 3]
                segmentation = np.where(ids < len(table), table[np.minimum(ids, len(table) - 1)], 0).astype(np.int32)
        position_m, quaternion = optical_pose(pose)
        return CameraFrame(
            camera=camera.model.name,
            sim_time_s=self.world.sim_time_s,
            intrinsics=np.asarray(sensor.get_intrinsic_matrix(), float),
            position_m=position_m,
            quaternion_wxyz=quaternion,
            rgb=rgb,
            depth_m=depth,
            segmentation=segmentation,
        )
