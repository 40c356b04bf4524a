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
