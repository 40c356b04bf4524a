"""`fleet bench perception`: how well the perception library sees a scene's parts through the scene's fixed
cameras: recall and precision per frame, position and yaw error against the world's truth, and what detecting
costs. The arms stand at home (no line runs): parts arrive and ride the belt as the scene's feeders release them.
The truth is read only to score; the detector is given colour, depth and the camera's pose alone."""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from fleet.common.scene_loading import load_checked_scene
from fleet.sim.cameras import labels
from fleet.sim.cameras.frames import CameraFrame
from fleet.sim.cameras.part_looks import part_looks
from fleet.sim.cameras.rig import CameraRig
from fleet.sim.cameras.seen_score import yaw_error_deg
from fleet.sim.world import World
from perception.detect import Detection, detect_parts
from perception.matching import nearest_pairs
from scenes.randomise import draw
from scenes.schema import Randomisation, Scene

GATE_M = 0.03  # a detection this close to a part of its kind is that part's
# what cameras see drawn per seed, over the ranges docs/scenes.md gives as its example (never the physics)
APPEARANCE = Randomisation.model_validate(
    {
        "light_yaw_deg": {"uniform": [-60, 60]},
        "light_intensity_scale": {"uniform": [0.6, 1.4]},
        "belt_grey": {"uniform": [0.05, 0.4]},
        "part_shade": {"uniform": [0.7, 1.3]},
        "camera_jitter_m": {"uniform": [0.0, 0.02]},
    }
)


@dataclass(frozen=True)
class PerceptionBenchRow:
    scene: str
    seed: int
    randomised: bool  # the appearance drawn from the seed (`APPEARANCE`)
    camera: str
    width_px: int
    height_px: int
    frames: int
    parts_visible: int  # part sightings: a part with a pixel in a frame, summed over frames
    recall: float  # of the parts visible in a frame, the share detected (of its kind, within the gate)
    precision: float  # of the detections, the share that are a part of their kind
    error_p50_mm: float
    error_p95_mm: float
    yaw_error_p50_deg: float
    yaw_error_p95_deg: float
    detect_ms: float  # wall time of one frame's detection


def _score(frame: CameraFrame, world: World, detections: list[Detection], kinds: dict) -> tuple[list, list, int]:
    """(position errors in mm, yaw errors in degrees, parts visible) of one frame; the detections matched to the
    parts with a pixel in it, the pairs chosen together."""
    visible = [p for p in world.active_parts() if (frame.segmentation == labels.part_label(p.part_id)).any()]
    pairs = nearest_pairs(
        np.array([p.position for p in visible]).reshape(-1, 3),
        [kinds[p.feeder, p.type_index] for p in visible],
        np.array([d.top_centre_m for d in detections]).reshape(-1, 3),
        [d.kind for d in detections],
        GATE_M,
    )
    errors, yaws = [], []
    for i, j, gap_m in pairs:
        errors.append(gap_m * 1000.0)
        if (yaw := yaw_error_deg(visible[i], detections[j].yaw_rad)) is not None:
            yaws.append(yaw)
    return errors, yaws, len(visible)


def scene_seen(scene_name: str, seed: int, randomised: bool) -> Scene:
    """The scene for `seed`; with `randomised`, its appearance drawn from the seed as well (`APPEARANCE`)."""
    scene = load_checked_scene(scene_name, seed=seed)  # its own ranges, if any, are drawn already
    return draw(scene.model_copy(update={"randomise": APPEARANCE})) if randomised else scene


def bench_perception(
    scene_name: str, seconds: float, scale: float = 1.0, seed: int = 0, randomised: bool = False
) -> list[PerceptionBenchRow]:
    """Every fixed camera of `scene_name` (its size times `scale`) at its rate for `seconds` of sim time."""
    scene = scene_seen(scene_name, seed, randomised)
    size = {"images": ["rgb", "depth", "segmentation"]}  # the segmentation only to score
    cameras = [
        c.model_copy(update=size | {"width_px": round(c.width_px * scale), "height_px": round(c.height_px * scale)})
        for c in scene.cameras
        if c.arm is None
    ]
    world = World(scene)
    rig = CameraRig(world, cameras)
    looks, kinds = part_looks(scene)
    found = {c.name: {"errors": [], "yaws": [], "visible": 0, "detections": 0, "frames": 0, "s": 0.0} for c in cameras}
    for _ in range(int(seconds / world.control_dt_s)):
        world.step(1)
        for name, frame in rig.frames(rig.due()).items():
            start = time.perf_counter()
            detections = detect_parts(frame.rgbd(), looks)
            counts = found[name]
            counts["s"] += time.perf_counter() - start
            errors, yaws, visible = _score(frame, world, detections, kinds)
            counts["errors"] += errors
            counts["yaws"] += yaws
            counts["visible"] += visible
            counts["detections"] += len(detections)
            counts["frames"] += 1
    return [_row(scene_name, seed, randomised, camera, found[camera.name]) for camera in cameras]


def _row(scene_name: str, seed: int, randomised: bool, camera, counts: dict) -> PerceptionBenchRow:
    errors, yaws = np.asarray(counts["errors"]), np.asarray(counts["yaws"])

    def pct(values: np.ndarray, q: float) -> float:
        return round(float(np.percentile(values, q)), 1) if len(values) else float("nan")

    return PerceptionBenchRow(
        scene_name,
        seed,
        randomised,
        camera.name,
        camera.width_px,
        camera.height_px,
        counts["frames"],
        counts["visible"],
        round(len(errors) / counts["visible"], 3) if counts["visible"] else float("nan"),
        round(len(errors) / counts["detections"], 3) if counts["detections"] else float("nan"),
        pct(errors, 50),
        pct(errors, 95),
        pct(yaws, 50),
        pct(yaws, 95),
        round(1000.0 * counts["s"] / max(1, counts["frames"]), 2),
    )
