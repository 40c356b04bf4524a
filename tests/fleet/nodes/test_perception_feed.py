"""The perception node's work without its process: a frame's colour and depth paired by tick, detected and tracked
into one `PartDetections`; anything on a camera key that cannot be a frame is dropped and counted, never a crash."""

import time

import msgspec
import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.bus.codec import encode
from fleet.bus.images import encode_image
from fleet.bus.messages import CameraImage, LineEvent, PartDetections, PartsState
from fleet.common.scene_loading import load_checked_scene
from fleet.nodes.perception_feed import PerceptionFeed
from fleet.sight.surfaces import belt_velocity_at

SCENE = load_checked_scene("pick_cell")
KEY = "clawfleet/line/camera/overhead/{}"
DOWN = (0.0, 1.0, 0.0, 0.0)  # wxyz: the optical +z turned to the world's -z
K = (100.0, 0.0, 30.0, 0.0, 100.0, 30.0, 0.0, 0.0, 1.0)


def drawn_frame(tick: int, camera_xy: tuple[float, float] = (0.0, 0.0)) -> tuple[CameraImage, CameraImage]:
    """A frame drawn by hand, from 1 m above the floor at `camera_xy` (1 cm a pixel): a 2 cm square of pick_cell's
    first part colour (#d04030) centred 1 cm along the world's +x and -y from it (the optical +y is the world's
    -y)."""
    rgb = np.full((60, 60, 3), 40, np.uint8)
    rgb[30:32, 30:32] = (208, 64, 48)
    depth = np.full((60, 60), 1.0, np.float32)
    common, at = (tick, tick / 100.0, 60, 60), (*camera_xy, 1.0)
    return (
        CameraImage("overhead", "rgb", *common, "raw", encode_image("rgb", rgb, "raw"), K, at, DOWN),
        CameraImage("overhead", "depth", *common, "raw", encode_image("depth", depth, "raw"), K, at, DOWN),
    )


def feed(seen: list[PartsState] | None = None) -> tuple[PerceptionFeed, list[PartDetections]]:
    out: list[PartDetections] = []
    publish_parts = (lambda msg: seen.append(msg)) if seen is not None else (lambda msg: None)
    return PerceptionFeed(SCENE, ["overhead"], lambda camera, msg: out.append(msg), publish_parts), out


def give(perceived: PerceptionFeed, key: str, payload: bytes) -> None:
    """One payload off the bus, then whatever frames are ready seen (as the node's loop does)."""
    perceived.take(key, payload)
    perceived.see()


def test_a_frame_becomes_one_message_and_a_part_seen_twice_a_track():
    perceived, out = feed()
    for tick in (20, 40):
        rgb, depth = drawn_frame(tick)
        give(perceived, KEY.format("depth"), encode(depth))  # either half may come first
        give(perceived, KEY.format("rgb"), encode(rgb))
    assert [m.tick for m in out] == [20, 40] and out[0].track_ids == (), "believed once seen in two frames"
    (track,) = out[1].track_ids
    assert out[1].kinds == (0,) and np.allclose(out[1].top_centres_m, (0.01, -0.01, 0.0), atol=1e-6), out[1]
    assert perceived.report()["frames"] == 2 and perceived.drops.total == 0


def test_a_frame_with_a_pose_that_is_not_one_is_dropped_and_depth_that_is_not_a_number_is_no_depth():
    perceived, out = feed()
    rgb, depth = drawn_frame(20)
    give(perceived, KEY.format("rgb"), encode(msgspec.structs.replace(rgb, quaternion_wxyz=(0.0, 0.0, 0.0, 0.0))))
    give(perceived, KEY.format("depth"), encode(depth))
    assert out == [] and perceived.drops.total == 1
    infinite = np.full((60, 60), np.inf, np.float32)
    depth = msgspec.structs.replace(depth, tick=40, data=encode_image("depth", infinite, "raw"))
    give(perceived, KEY.format("rgb"), encode(msgspec.structs.replace(rgb, tick=40)))
    give(perceived, KEY.format("depth"), encode(depth))
    assert len(out) == 1 and out[0].track_ids == () and perceived.drops.total == 1


def test_halves_of_two_different_frames_are_never_paired():
    perceived, out = feed()
    give(perceived, KEY.format("rgb"), encode(drawn_frame(20)[0]))
    give(perceived, KEY.format("depth"), encode(drawn_frame(40)[1]))
    assert out == []


def test_a_frame_whose_depth_comes_after_the_next_frames_colour_is_still_seen():
    perceived, out = feed()
    (rgb_20, depth_20), (rgb_40, depth_40) = drawn_frame(20), drawn_frame(40)
    for key, image in (("rgb", rgb_20), ("rgb", rgb_40), ("depth", depth_20), ("depth", depth_40)):
        give(perceived, KEY.format(key), encode(image))  # two keys, two callbacks: no order between them
    assert [m.tick for m in out] == [20, 40]


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
        give(perceived, KEY.format(leaf), payload)
    report = perceived.report()
    assert report["frames"] == len(out)
    assert all(np.isfinite(m.top_centres_m).all() for m in out)


def test_a_frame_waits_for_the_events_before_it_and_the_part_released_then_is_seen_where_its_track_is():
    seen: list[PartsState] = []
    perceived, out = feed(seen)
    feeder = SCENE.feeders[0]
    x, y, _ = SCENE.conveyor.point_at(SCENE.drop_along_m(feeder))  # where the feeder sets its parts down
    for tick in (20, 40):
        rgb, depth = drawn_frame(tick, (x - 0.01, y + 0.01))
        give(perceived, KEY.format("rgb"), encode(msgspec.structs.replace(rgb, events_published=1)))
        give(perceived, KEY.format("depth"), encode(msgspec.structs.replace(depth, events_published=1)))
    assert out == [] and seen == [], "the frames wait for the event the sim had published before them"
    give(perceived, "clawfleet/line/world/events", encode(LineEvent("arrived", 5, 10, feeder.name, 0)))
    assert [m.tick for m in seen] == [20, 40] and seen[0].part_ids == ()
    assert seen[1].part_ids == (5,) and seen[1].feeders == (feeder.name,) and seen[1].events_published == 1
    height = feeder.parts[0].size_m[2]
    assert np.allclose(seen[1].positions, (x, y, -height / 2), atol=1e-6), "its centre, half its height down"


def test_an_event_the_sim_published_after_a_frame_waits_for_the_next_frame_however_soon_it_arrives():
    """Events travel above the images (`Priority.DATA_LOW`): one of the frame's own tick, published after the frame
    was taken, may come first. Applied then, runs of one seed would bind their parts differently."""
    seen: list[PartsState] = []
    perceived, _ = feed(seen)
    feeder = SCENE.feeders[0]
    x, y, _ = SCENE.conveyor.point_at(SCENE.drop_along_m(feeder))
    perceived.take("clawfleet/line/world/events", encode(LineEvent("arrived", 5, 20, feeder.name, 0)))
    for tick, published in ((20, 0), (40, 1)):
        rgb, depth = drawn_frame(tick, (x - 0.01, y + 0.01))
        perceived.take(KEY.format("rgb"), encode(msgspec.structs.replace(rgb, events_published=published)))
        perceived.take(KEY.format("depth"), encode(msgspec.structs.replace(depth, events_published=published)))
        perceived.see()
        if tick == 20:
            assert [e.part_id for _, _, e in perceived.sight.held] == [5], "held past the frame it came after"
    assert [(m.tick, m.part_ids) for m in seen] == [(20, ()), (40, (5,))] and perceived.sight.held == []
    # and each frame's message counts the events applied to it, not those heard by then (CI once had 0 and 1)
    assert [m.events_published for m in seen] == [0, 1]
    assert perceived.report()["frames_on_deadline"] == 0


def test_a_frame_whose_events_never_come_is_seen_once_its_wait_is_over():
    seen: list[PartsState] = []
    perceived, _ = feed(seen)
    rgb, depth = drawn_frame(20)
    perceived.take(KEY.format("rgb"), encode(msgspec.structs.replace(rgb, events_published=3)))
    perceived.take(KEY.format("depth"), encode(depth))
    assert perceived.see() == 0 and perceived.see(now_s=time.monotonic() + 1.0) == 1
    assert perceived.report()["frames_on_deadline"] == 1


@settings(max_examples=200, deadline=None)
@given(
    st.builds(
        LineEvent,
        st.sampled_from(["arrived", "at_station", "lost", "retired", "exploded"]),
        st.integers(-3, 9),
        st.integers(-3, 100),
        st.sampled_from(["", "tray", "feeder", "parts", "bin_a"]) | st.text(max_size=8),
        st.integers(-2, 4),
    )
    | st.binary(max_size=30)
)
def test_whatever_comes_on_the_events_key_is_an_event_of_this_line_or_dropped_and_counted(event):
    seen: list[PartsState] = []
    perceived, _ = feed(seen)
    give(perceived, "clawfleet/line/world/events", event if isinstance(event, bytes) else encode(event))
    rgb, depth = drawn_frame(200)
    give(perceived, KEY.format("rgb"), encode(rgb))
    give(perceived, KEY.format("depth"), encode(depth))
    assert len(seen) == 1 and all(pid >= 0 for pid in seen[0].part_ids)
    assert perceived.drops.total + len(perceived.sight.held) + len(perceived.sight.types) <= 1
