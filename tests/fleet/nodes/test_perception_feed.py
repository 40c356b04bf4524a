"""The perception node's work without its process: a frame's colour and depth paired by tick, detected and tracked
into one `PartDetections`; anything on a camera key that cannot be a frame is dropped and counted, never a crash."""

import msgspec
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.bus.codec import encode
from fleet.bus.images import encode_image
from fleet.bus.messages import CameraImage, PartDetections
from fleet.common.scene_loading import load_checked_scene
from fleet.nodes.perception_feed import PerceptionFeed, belt_velocity_at

SCENE = load_checked_scene("pick_cell")
KEY = "clawfleet/line/camera/overhead/{}"
DOWN = (0.0, 1.0, 0.0, 0.0)  # wxyz: the optical +z turned to the world's -z
K = (100.0, 0.0, 30.0, 0.0, 100.0, 30.0, 0.0, 0.0, 1.0)


def drawn_frame(tick: int) -> tuple[CameraImage, CameraImage]:
    """A frame drawn by hand, 1 m above the floor (1 cm a pixel): a 2 cm square of pick_cell's first part colour
    (#d04030) centred 1 cm along the world's +x and -y (the optical +y is the world's -y)."""
    rgb = np.full((60, 60, 3), 40, np.uint8)
    rgb[30:32, 30:32] = (208, 64, 48)
    depth = np.full((60, 60), 1.0, np.float32)
    common = (tick, tick / 100.0, 60, 60)
    return (
        CameraImage("overhead", "rgb", *common, "raw", encode_image("rgb", rgb, "raw"), K, (0.0, 0.0, 1.0), DOWN),
        CameraImage("overhead", "depth", *common, "raw", encode_image("depth", depth, "raw"), K, (0.0, 0.0, 1.0), DOWN),
    )


def feed() -> tuple[PerceptionFeed, list[PartDetections]]:
    out: list[PartDetections] = []
    return PerceptionFeed(SCENE, ["overhead"], lambda camera, msg: out.append(msg)), out


def test_a_frame_becomes_one_message_and_a_part_seen_twice_a_track():
    perceived, out = feed()
    for tick in (20, 40):
        rgb, depth = drawn_frame(tick)
        perceived.take(KEY.format("depth"), encode(depth))  # either half may come first
        perceived.take(KEY.format("rgb"), encode(rgb))
    assert [m.tick for m in out] == [20, 40] and out[0].track_ids == (), "believed once seen in two frames"
    (track,) = out[1].track_ids
    assert out[1].kinds == (0,) and np.allclose(out[1].top_centres_m, (0.01, -0.01, 0.0), atol=1e-6), out[1]
    assert perceived.report()["frames"] == 2 and perceived.drops.total == 0


def test_a_frame_with_a_pose_that_is_not_one_is_dropped_and_depth_that_is_not_a_number_is_no_depth():
    perceived, out = feed()
    rgb, depth = drawn_frame(20)
    perceived.take(KEY.format("rgb"), encode(msgspec.structs.replace(rgb, quaternion_wxyz=(0.0, 0.0, 0.0, 0.0))))
    perceived.take(KEY.format("depth"), encode(depth))
    assert out == [] and perceived.drops.total == 1
    infinite = np.full((60, 60), np.inf, np.float32)
    depth = msgspec.structs.replace(depth, tick=40, data=encode_image("depth", infinite, "raw"))
    perceived.take(KEY.format("rgb"), encode(msgspec.structs.replace(rgb, tick=40)))
    perceived.take(KEY.format("depth"), encode(depth))
    assert len(out) == 1 and out[0].track_ids == () and perceived.drops.total == 1


def test_halves_of_two_different_frames_are_never_paired():
    perceived, out = feed()
    perceived.take(KEY.format("rgb"), encode(drawn_frame(20)[0]))
    perceived.take(KEY.format("depth"), encode(drawn_frame(40)[1]))
    assert out == []


def test_the_belt_carries_only_what_lies_on_it():
    velocity_at = belt_velocity_at(load_checked_scene("sorting_line"))
    belt = load_checked_scene("sorting_line").conveyor
    on = np.asarray(belt.point_at(0.5)) + [0, 0, 0.03]
    assert np.allclose(velocity_at(on), np.asarray(belt.direction) * belt.speed_m_per_s)
    assert not velocity_at(on + [0, belt.width_m, 0]).any() and not velocity_at(on + [0, 0, 0.5]).any()


IMAGES = st.builds(
    CameraImage,
    st.sampled_from(["overhead", "wrist", ""]),
    st.sampled_from(["rgb", "depth", "segmentation", "x"]),
    st.integers(0, 50),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(-2, 70),
    st.integers(-2, 70),
    st.sampled_from(["raw", "png", "jpeg", "png16", "zlib", "?"]),
    st.binary(max_size=64) | st.just(b"\x00" * 60 * 60 * 4),
    st.lists(st.floats(allow_nan=True), max_size=10).map(tuple),
    st.lists(st.floats(-5, 5), max_size=4).map(tuple),
    st.lists(st.floats(-1, 1), max_size=5).map(tuple),
)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["rgb", "depth", "other"]), IMAGES | st.binary(max_size=40)), max_size=6))
def test_whatever_comes_on_a_camera_key_is_a_frame_or_dropped_and_counted_never_a_crash(messages):
    perceived, out = feed()
    for leaf, message in messages:
        payload = message if isinstance(message, bytes) else encode(message)
        perceived.take(KEY.format(leaf), payload)
    report = perceived.report()
    assert report["frames"] == len(out)
    assert all(np.isfinite(m.top_centres_m).all() for m in out)
