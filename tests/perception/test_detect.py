"""Parts found in frames SAPIEN rendered (on the CPU where no GPU is): each where the world holds it, of its kind,
from the pixels alone; and a frame's detections follow the frame, not the world it was taken of."""

import numpy as np
import pytest

from fleet.common.scene_loading import load_checked_scene
from fleet.sim.cameras.rig import CameraRig
from fleet.sim.world import PartInfo, World
from perception.detect import detect_parts
from perception.looks import PartLook
from perception.rgbd import RGBDFrame
from scenes.schema import Camera, Scene


def looks_of(scene: Scene) -> tuple[list[PartLook], dict[tuple[str, int], int]]:
    """One look per feeder's part type, and the look's kind by (feeder, type index)."""
    looks, kinds = [], {}
    for feeder in scene.feeders:
        for index, part in enumerate(feeder.parts):
            kinds[feeder.name, index] = len(looks)
            looks.append(PartLook(len(looks), part.rgb))
    return looks, kinds


def rgbd(frame) -> RGBDFrame:
    """What perception is given of a rendered frame: colour, depth, intrinsics and pose (no segmentation)."""
    return RGBDFrame(
        frame.camera, frame.sim_time_s, frame.rgb, frame.depth_m, frame.intrinsics, frame.position_m,
        frame.quaternion_wxyz,
    )  # fmt: skip


def camera_over(xy, height_m: float = 0.5, size_px: int = 200) -> Camera:
    x, y = xy
    return Camera(
        name="close",
        pose={"xyz": (x, y, height_m), "look_at": (x, y, 0.0), "up": (0.0, 1.0, 0.0)},
        width_px=size_px,
        height_px=size_px,
        fov_deg=50,
        images=["rgb", "depth"],
    )


def nearest(detections, part: PartInfo):
    return min(detections, key=lambda d: np.linalg.norm(np.subtract(d.top_centre_m[:2], part.position[:2])))


def test_each_part_under_a_close_camera_is_found_of_its_kind_within_5_mm():
    scene = load_checked_scene("pick_cell")
    world = World(scene)
    world.step(1500)
    parts = world.active_parts()
    assert len(parts) >= 3
    looks, kinds = looks_of(scene)
    centre = np.mean([p.position[:2] for p in parts], axis=0)
    detections = detect_parts(rgbd(CameraRig(world, [camera_over(centre)]).frames()["close"]), looks)
    assert len(detections) == len(parts), (detections, [p.position for p in parts])
    for part in parts:
        seen = nearest(detections, part)
        assert seen.kind == kinds[part.feeder, part.type_index]
        assert np.linalg.norm(np.subtract(seen.top_centre_m[:2], part.position[:2])) < 0.005, (seen, part.position)
        assert abs(seen.top_centre_m[2] - (part.position[2] + part.height_m / 2)) < 0.005
        assert seen.confidence > 0.3


def test_the_overhead_camera_of_a_belt_line_finds_every_part_on_the_belt_within_one_pixel():
    scene = load_checked_scene("mixed_infeed")
    world = World(scene)
    world.step(1500)
    looks, kinds = looks_of(scene)
    frame = CameraRig(world).frames()["overhead"]
    metres_per_px = frame.depth_m[frame.depth_m > 0].max() / frame.intrinsics[0, 0]
    detections = detect_parts(rgbd(frame), looks)
    on_belt = [p for p in world.active_parts() if p.feeder == "belt_parts"]
    assert on_belt
    for part in on_belt:
        seen = nearest(detections, part)
        assert seen.kind == kinds[part.feeder, part.type_index]
        assert np.linalg.norm(np.subtract(seen.top_centre_m[:2], part.position[:2])) < metres_per_px, (seen, part)


def test_detections_follow_the_frame_not_the_world_it_was_taken_of():
    """The world's parts moved after the frame was rendered: the frame's detections stay where the parts were."""
    scene = load_checked_scene("pick_cell")
    world = World(scene)
    world.step(1500)
    looks, _ = looks_of(scene)
    parts = world.active_parts()
    rig = CameraRig(world, [camera_over(np.mean([p.position[:2] for p in parts], axis=0))])
    before = rgbd(rig.frames()["close"])
    for part in (p for p in world.parts if p.active):  # the test moves the parts (perception never sees the world)
        pose = part.entity.pose
        part.entity.pose = type(pose)([pose.p[0] + 0.03, pose.p[1], pose.p[2]], pose.q)
    seen_before = detect_parts(before, looks)
    for part in parts:
        assert np.linalg.norm(np.subtract(nearest(seen_before, part).top_centre_m[:2], part.position[:2])) < 0.005
    seen_after = detect_parts(rgbd(rig.frames()["close"]), looks)
    for part in parts:
        moved = part.position[:2] + [0.03, 0.0]
        assert np.linalg.norm(np.subtract(nearest(seen_after, part).top_centre_m[:2], moved)) < 0.005


def test_a_frame_whose_colour_and_depth_differ_in_size_is_refused():
    with pytest.raises(ValueError, match="differ in size"):
        RGBDFrame("c", 0.0, np.zeros((4, 4, 3), np.uint8), np.zeros((4, 5), np.float32), np.eye(3), np.zeros(3),
                  np.array([1.0, 0, 0, 0]))  # fmt: skip
