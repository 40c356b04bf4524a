"""`fleet run --cameras`: a line's cameras render at their rates in sim time, their images travel the bus into the
recording as ROS images that readers we did not write decode, and a lockstep run repeats them to the byte."""

import io
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from PIL import Image
from rosbags.highlevel import AnyReader

from tests.fleet.test_run import assert_nothing_left, run_lines_together

pytestmark = pytest.mark.slow  # whole runs

SECONDS = 2.0
SNAPSHOT_S = 1.0


def ros_images(path: Path) -> dict[str, list]:
    """Every camera topic's decoded messages, read with mcap-ros2-support."""
    seen: dict[str, list] = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        topics = [
            c.topic for c in reader.get_summary().channels.values() if c.topic.startswith(("/overhead/", "/wrist/"))
        ]
        for _, channel, _, decoded in reader.iter_decoded_messages(topics=topics):
            seen.setdefault(channel.topic, []).append(decoded)
    return seen


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    """pick_cell (overhead and wrist cameras), twice with one seed, each recorded, each with a snapshot at 1 s."""
    folder = tmp_path_factory.mktemp("cameras")
    options = [
        {
            "scene": "pick_cell",
            "duration_s": SECONDS,
            "seed": 3,
            "cameras": "all",
            "record": str(folder / f"{k}.mcap"),
            "snapshot_at": (SNAPSHOT_S,),
            "snapshot_dir": str(folder / f"snapshots_{k}"),
        }
        for k in (0, 1)
    ]
    runs = run_lines_together(*options)
    for summary, launcher in runs:
        assert_nothing_left(summary, launcher.endpoint)
    return [(summary, Path(o["record"])) for (summary, _), o in zip(runs, options)]


def stamped(messages: list) -> dict[float, bytes]:
    """Image messages' bytes by their sim time stamp."""
    return {m.header.stamp.sec + m.header.stamp.nanosec * 1e-9: bytes(m.data) for m in messages}


def test_each_camera_makes_its_frames_at_its_rate_in_sim_time(two_runs):
    summary, _ = two_runs[0]
    cameras = summary["cameras"]
    assert cameras["frames_by_camera"] == {"overhead": 10, "wrist": 20}  # 5 Hz and 10 Hz over 2 sim seconds
    assert cameras["images"] == 3 * 30 and cameras["bytes_out"] > 0


def test_the_recording_holds_every_cameras_images_as_ros_messages_that_decode(two_runs):
    _, path = two_runs[0]
    seen = ros_images(path)
    counts = Counter({topic: len(messages) for topic, messages in seen.items()})
    for camera, frames in (("overhead", 10), ("wrist", 20)):
        for topic in ("image_raw/compressed", "depth/image_raw", "segmentation/image_raw", "camera_info"):
            assert counts[f"/{camera}/{topic}"] == frames, (camera, topic, counts)
    colour = seen["/overhead/image_raw/compressed"][-1]
    picture = np.asarray(Image.open(io.BytesIO(bytes(colour.data))))
    assert picture.shape == (120, 160, 3) and picture.std() > 10, "the picture shows the cell, not one colour"
    assert colour.header.frame_id == "overhead_optical_frame"
    info = seen["/overhead/camera_info"][-1]
    assert (info.width, info.height) == (160, 120) and info.k[0] > 0
    depth = seen["/wrist/depth/image_raw"][-1]
    assert depth.encoding == "16UC1" and np.frombuffer(bytes(depth.data), "<u2").max() > 0


def test_each_cameras_optical_frame_hangs_on_its_mount_in_tf_static(two_runs):
    _, path = two_runs[0]
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        static = [d for _, _, _, d in reader.iter_decoded_messages(topics=["/tf_static"])]
    parents = {t.child_frame_id: t.header.frame_id for message in static for t in message.transforms}
    assert parents["overhead_optical_frame"] == "world"
    assert parents["wrist_optical_frame"] == "arm_0/tool_link" and "arm_0/tool_link" in parents


def test_rosbags_reads_the_same_images(two_runs):
    _, path = two_runs[0]
    with AnyReader([path]) as reader:
        wanted = [c for c in reader.connections if c.topic == "/wrist/image_raw/compressed"]
        pictures = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=wanted)]
    assert len(pictures) == 20 and pictures[0].format == "png"
    assert Image.open(io.BytesIO(bytes(pictures[-1].data))).size == (128, 96)


def test_a_lockstep_run_and_its_seed_repeat_their_images_to_the_byte(two_runs):
    (_, first), (_, second) = two_runs
    a, b = ros_images(first), ros_images(second)
    for topic in ("/overhead/image_raw/compressed", "/wrist/depth/image_raw", "/overhead/segmentation/image_raw"):
        assert [bytes(m.data) for m in a[topic]] == [bytes(m.data) for m in b[topic]], topic


def test_the_report_makes_a_contact_sheet_and_an_animation_of_each_camera(two_runs, tmp_path):
    from fleet.cli import main

    _, path = two_runs[0]
    assert main(["report", str(path), "--out", str(tmp_path / "report")]) == 0
    for camera, size in (("overhead", (160, 120)), ("wrist", (128, 96))):
        sheet = Image.open(tmp_path / "report" / f"{camera}_sheet.png")
        assert sheet.width == 4 * size[0] and np.asarray(sheet).std() > 10
        animation = Image.open(tmp_path / "report" / f"{camera}.gif")
        assert animation.size == size and animation.n_frames >= 2  # (identical frames in a row are merged)


def test_a_line_with_cameras_snapshots_and_its_restore_sees_what_the_whole_run_saw(two_runs, tmp_path):
    from tests.fleet.test_run import run_line

    summary, path = two_runs[0]
    assert summary["snapshots_failed"] == [] and len(summary["snapshots"]) == 1, "the renderer is no part of a state"
    restored, launcher = run_line(
        scene="pick_cell",
        restore_from=summary["snapshots"][0],
        duration_s=SECONDS,  # the sim time to end at
        cameras="all",
        record=str(tmp_path / "restored.mcap"),
    )
    assert_nothing_left(restored, launcher.endpoint)
    assert restored["status"] == "ok", restored.get("error")
    assert restored["cameras"]["frames_by_camera"] == {"overhead": 5, "wrist": 10}  # 1.0 s to 2.0 s
    whole, after = ros_images(path), ros_images(tmp_path / "restored.mcap")
    for topic in ("/overhead/image_raw/compressed", "/wrist/depth/image_raw", "/wrist/segmentation/image_raw"):
        later = {t: data for t, data in stamped(whole[topic]).items() if t >= SNAPSHOT_S - 1e-6}
        assert stamped(after[topic]) == later, topic
