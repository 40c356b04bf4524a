"""A clawfleet allocator plug-in that sees: it looks at the line's overhead camera twice a sim second and decides
where the parts are from the image alone.

An allocator that declares `frames_hz` is handed the fixed cameras' RGB-D frames (`see(frames)`, each a
`perception.rgbd.RGBDFrame`: colour, depth, intrinsics and the camera's pose, never the segmentation) before a
decision, at most that often (docs/allocators.md, "An allocator that sees"). This one finds the parts in the image
itself with clawfleet's perception library (`perception.detect`: each part type's colour), names each detection
after the task's part nearest it, and then gives each free arm the open task whose part, *where the image shows it*,
lies nearest the arm's base among those it can serve. A task whose part its last look did not show waits.
"""

from __future__ import annotations

import math

import numpy as np

from coordinator.allocation import ArmView, Eligibility, PartView, open_candidates
from coordinator.tasks import Task
from perception.detect import Detection, detect_parts
from perception.looks import PartLook
from perception.rgbd import RGBDFrame
from scenes.schema import Scene

NAMING_GATE_M = 0.05  # a detection names the task's part nearest it within this (x-y)


def looks_of(scene: Scene) -> list[PartLook]:
    """One look per colour and size of the scene's part types: parts that look alike are one kind to a camera."""
    seen_as = dict.fromkeys((part.rgb, tuple(part.size_m)) for feeder in scene.feeders for part in feeder.parts)
    return [PartLook(kind, rgb, size_m) for kind, (rgb, size_m) in enumerate(seen_as)]


class OverheadEyes:
    """Decides from the overhead image: each free arm takes the task whose part the image shows nearest it."""

    name = "overhead_eyes"
    frames_hz = 2.0  # looks per sim second

    def __init__(self, scene: Scene) -> None:
        self.scene = scene
        self.looks = looks_of(scene)
        self.detections: list[Detection] = []
        self.looked = 0

    def see(self, frames: list[RGBDFrame]) -> None:
        """The parts in the cameras' newest frames, found in their pixels."""
        self.detections = [d for frame in frames for d in detect_parts(frame, self.looks)]
        self.looked += 1

    def allocate(
        self, tasks: list[Task], arms: list[ArmView], parts: dict[int, PartView], busy_stations: set[str]
    ) -> list[tuple[int, str]]:
        rules = Eligibility(self.scene, arms)
        seen = self._seen_where(open_candidates(tasks, parts, busy_stations), parts)
        busy, out, taken = set(busy_stations), [], set()
        for arm in sorted((a for a in arms if a.free), key=lambda a: a.name):
            open_now = [(t, v) for t, v in seen if t.part_id not in taken and not busy.intersection(t.stations)]
            choices = [
                (math.dist(arm.base_xyz[:2], view.position[:2]), task.task_id, task)
                for task, view in open_now
                if rules.can_serve(arm, task, view)
            ]
            if choices:
                _, _, task = min(choices)
                out.append((task.task_id, arm.name))
                taken.add(task.part_id)
                busy.update(task.stations)
        return out

    def _seen_where(self, tasks: list[Task], parts: dict[int, PartView]) -> list[tuple[Task, PartView]]:
        """Each task whose part the last look showed, with the part where the image shows it (riding as the line
        says it rides): a detection names the task's part nearest it."""
        out = []
        for task in sorted(tasks, key=lambda t: t.task_id):
            said = parts[task.part_id]
            near = [d for d in self.detections if math.dist(d.top_centre_m[:2], said.position[:2]) <= NAMING_GATE_M]
            if near:
                best = min(near, key=lambda d: math.dist(d.top_centre_m[:2], said.position[:2]))
                out.append((task, PartView(np.asarray(best.top_centre_m, float), said.velocity)))
        return out
