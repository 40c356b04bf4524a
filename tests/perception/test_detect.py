"""Parts found in frames SAPIEN rendered (on the CPU where no GPU is): each where the world holds it, of its kind,
from the pixels alone; and a frame's detections follow the frame, not the world it was taken of."""

import numpy as np
import pytest

from fleet.common.scene_loading import load_checked_scene
from fleet.sim.cameras.part_looks import part_looks
from fleet.sim.cameras.rig import CameraRig
from fleet.sim.world import PartInfo, World
from perception.detect import detect_parts
from perception.looks import PartLook
from perception.rgbd import RGBDFrame
from scenes.schema import Camera


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
    looks, kinds = part_looks(scene)
    centre = np.mean([p.position[:2] for p in parts], axis=0)
    detections = detect_parts(CameraRig(world, [camera_over(centre)]).frames()["close"].rgbd(), looks)
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
    looks, kinds = part_looks(scene)
    frame = CameraRig(world).frames()["overhead"]
    metres_per_px = frame.depth_m[frame.depth_m > 0].max() / frame.intrinsics[0, 0]
    detections = detect_parts(frame.rgbd(), looks)
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
    looks, _ = part_looks(scene)
    parts = world.active_parts()
    rig = CameraRig(world, [camera_over(np.mean([p.position[:2] for p in parts], axis=0))])
    before = rig.frames()["close"].rgbd()
    for part in (p for p in world.parts if p.active):  # the test moves the parts (perception never sees the world)
        pose = part.entity.pose
        part.entity.pose = type(pose)([pose.p[0] + 0.03, pose.p[1], pose.p[2]], pose.q)
    seen_before = detect_parts(before, looks)
    for part in parts:
        assert np.linalg.norm(np.subtract(nearest(seen_before, part).top_centre_m[:2], part.position[:2])) < 0.005
    seen_after = detect_parts(rig.frames()["close"].rgbd(), looks)
    for part in parts:
        moved = part.position[:2] + [0.03, 0.0]
        assert np.linalg.norm(np.subtract(nearest(seen_after, part).top_centre_m[:2], moved)) < 0.005


def test_a_frame_whose_colour_and_depth_differ_in_size_is_refused():
    with pytest.raises(ValueError, match="differ in size"):
        RGBDFrame("c", 0.0, np.zeros((4, 4, 3), np.uint8), np.zeros((4, 5), np.float32), np.eye(3), np.zeros(3),
                  np.array([1.0, 0, 0, 0]))  # fmt: skip


def test_a_blob_of_a_parts_colour_much_longer_than_the_part_is_not_taken_for_one():
    """An arm's link painted like a part (a bar 30 pixels long, 0.3 m at 1 m) beside a part-sized square: only the
    square is a part. A frame drawn by hand: 1 m straight down, 100 px focal length (1 cm a pixel)."""
    rgb = np.full((60, 60, 3), 40, np.uint8)
    blue = (48, 112, 208)
    rgb[10:13, 10:40] = blue  # the bar
    rgb[40:44, 40:44] = blue  # the part, 4 cm square
    depth = np.full((60, 60), 1.0, np.float32)
    k = np.array([[100.0, 0, 30], [0, 100.0, 30], [0, 0, 1]])
    down = np.array([0.0, 1.0, 0.0, 0.0])  # wxyz: the optical +z turned to the world's -z
    frame = RGBDFrame("drawn", 1.0, rgb, depth, k, np.array([0.0, 0.0, 1.0]), down)
    (found,) = detect_parts(frame, [PartLook(7, (48 / 255, 112 / 255, 208 / 255), (0.04, 0.04, 0.03))])
    assert found.kind == 7 and found.pixels == 16 and found.top_centre_m[2] == pytest.approx(0.0, abs=1e-6)
    assert detect_parts(frame, [PartLook(7, (48 / 255, 112 / 255, 208 / 255))])[0].pixels == 90, "any size: both"
