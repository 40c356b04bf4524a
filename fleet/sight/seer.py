"""One line's sight over its cameras' frames: each frame's parts detected (`perception.detect`) and tracked per
camera (`perception.tracks`), the tracks bound to the parts the line's events name (`LineSight`). The perception
process and the env's `perception="cameras"` drive the same object."""

from __future__ import annotations

import time

from fleet.sight.line_sight import LineSight
from fleet.sight.surfaces import belt_velocity_at, rests_at
from fleet.sim.cameras.part_looks import part_looks
from perception.detect import detect_parts
from perception.rgbd import RGBDFrame
from perception.tracks import PartTracks, Track
from scenes.schema import Scene


class Seer:
    """Sees `cameras`' frames (`frame`) of `scene`; its `sight` is told the line's events by whoever hears them."""

    def __init__(self, scene: Scene, cameras: list[str]) -> None:
        self.looks, kinds = part_looks(scene)
        velocity_at = belt_velocity_at(scene)
        self.tracks = {name: PartTracks(velocity_at, rests_at=rests_at(scene)) for name in cameras}
        self.sight = LineSight(scene, self.looks, kinds, velocity_at)
        self.detect_s: list[float] = []

    def frame(self, camera: str, frame: RGBDFrame) -> list[Track]:
        """One camera frame seen: its believed tracks, the line's parts following them."""
        start = time.perf_counter()
        believed = self.tracks[camera].update(detect_parts(frame, self.looks), frame.sim_time_s)
        self.sight.update(camera, believed, frame.sim_time_s)
        self.detect_s.append(time.perf_counter() - start)
        return believed
