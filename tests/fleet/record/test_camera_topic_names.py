"""A camera's ROS topic names, spelled once, in image_transport's layout, for the recording and the live front ends."""

from fleet.record.camera_to_ros import CameraTopics, camera_topic_types


def test_colour_goes_raw_or_compressed_and_other_kinds_under_their_own_names():
    topics = CameraTopics("overhead")
    assert topics.image("rgb", "raw") == "/overhead/image_raw"
    assert topics.image("rgb", "png") == topics.image("rgb", "jpeg") == "/overhead/image_raw/compressed"
    assert topics.image("depth", "png16") == "/overhead/depth/image_raw"
    assert topics.image("segmentation", "zlib") == "/overhead/segmentation/image_raw"
    assert topics.info == "/overhead/camera_info"


def test_the_live_topics_are_the_names_the_recording_uses():
    types = camera_topic_types("wrist", ["rgb", "depth"])
    assert types == {
        "/wrist/camera_info": "sensor_msgs/msg/CameraInfo",
        "/wrist/image_raw": "sensor_msgs/msg/Image",
        "/wrist/image_raw/compressed": "sensor_msgs/msg/CompressedImage",
        "/wrist/depth/image_raw": "sensor_msgs/msg/Image",
    }
    assert "/wrist/segmentation/image_raw" not in types


def test_a_recording_holds_the_same_ros_messages_whichever_way_the_images_travelled():
    import io

    import numpy as np
    from PIL import Image

    from fleet.bus.images import encodings_for
    from fleet.record.camera_to_ros import camera_topics
    from fleet.sim.cameras.frames import CameraFrame
    from fleet.sim.cameras.line_cameras import image_messages

    rng = np.random.default_rng(7)
    frame = CameraFrame(
        "overhead",
        1.5,
        np.array([[80.0, 0, 40], [0, 80, 30], [0, 0, 1]]),
        np.zeros(3),
        np.array([1.0, 0, 0, 0]),
        rgb=rng.integers(0, 256, (60, 80, 3), dtype=np.uint8),
        depth_m=rng.uniform(0.3, 1.2, (60, 80)).astype(np.float32),
        segmentation=rng.integers(0, 50, (60, 80), dtype=np.int32),
    )

    def recorded(rgb_encoding: str) -> dict:
        out = {}
        for message in image_messages(frame, 150, encodings_for(rgb_encoding)):
            for topic, make in camera_topics(message, first_of_frame=False):
                out[topic] = make()
        return out

    packed, raw = recorded("png"), recorded("raw")
    assert (
        sorted(packed)
        == sorted(raw)
        == [
            "/overhead/depth/image_raw",
            "/overhead/image_raw/compressed",
            "/overhead/segmentation/image_raw",
        ]
    )
    for ros in (packed, raw):
        colour = ros["/overhead/image_raw/compressed"]
        assert colour.format == "png", "a raw array is packed as PNG by the recorder"
        assert np.array_equal(np.asarray(Image.open(io.BytesIO(bytes(colour.data)))), frame.rgb)
        depth = ros["/overhead/depth/image_raw"]
        assert depth.encoding == "16UC1"
        millimetres = np.frombuffer(bytes(depth.data), "<u2").reshape(60, 80)
        assert np.array_equal(millimetres, np.rint(frame.depth_m * 1000).astype(np.uint16))
    assert bytes(packed["/overhead/segmentation/image_raw"].data) == bytes(raw["/overhead/segmentation/image_raw"].data)
