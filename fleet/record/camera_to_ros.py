"""A camera's images as ROS 2 messages, named as ROS camera drivers name them.

For a camera `<camera>`: colour on `/<camera>/image_raw/compressed` (`sensor_msgs/CompressedImage`, png or jpeg)
and, live, `/<camera>/image_raw` (`sensor_msgs/Image` rgb8); depth on `/<camera>/depth/image_raw` (`sensor_msgs/Image`,
16UC1 millimetres, 0 where nothing is seen); segmentation on `/<camera>/segmentation/image_raw`
(32SC1 ids, `fleet.sim.cameras.labels`); `/<camera>/camera_info` with each frame; and the optical frame
`<camera>_optical_frame` (+z forward, +x right, +y down) on `/tf_static` under its mount (`world`, or the arm's
link `<arm>/<link>` it rides on).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from fleet.bus.images import decode_image, encode_image
from fleet.bus.messages import CameraImage
from fleet.record.ros_types import ros_type, time_msg
from scenes.schema import CameraPlacement, Scene

WORLD = "world"
IMAGE_ENCODINGS = {("rgb", "raw"): "rgb8", ("rgb", "png"): "rgb8", ("rgb", "jpeg"): "rgb8"}
IMAGE_ENCODINGS |= {("depth", "raw"): "16UC1", ("depth", "png16"): "16UC1"}  # however it travelled
IMAGE_ENCODINGS[("segmentation", "raw")] = IMAGE_ENCODINGS[("segmentation", "zlib")] = "32SC1"


def optical_frame(camera: str) -> str:
    return f"{camera}_optical_frame"


@dataclass(frozen=True)
class CameraTopics:
    """The one spelling of a camera's ROS topic names, as image_transport lays them out."""

    camera: str

    @property
    def info(self) -> str:
        return f"/{self.camera}/camera_info"

    @property
    def colour_raw(self) -> str:
        return f"/{self.camera}/image_raw"

    @property
    def colour_compressed(self) -> str:
        return f"/{self.camera}/image_raw/compressed"

    def image(self, kind: str, encoding: str = "raw") -> str:
        """The topic an image of `kind` goes out on (colour: raw or compressed by its encoding)."""
        if kind == "rgb":
            return self.colour_raw if encoding == "raw" else self.colour_compressed
        return f"/{self.camera}/{kind}/image_raw"


def image_topic(message: CameraImage) -> str:
    """The ROS topic a camera image goes out on in a recording (colour compressed, however it travelled)."""
    return CameraTopics(message.camera).image(message.kind, "png")


def camera_topic_types(camera: str, kinds: list[str]) -> dict[str, str]:
    """Every live ROS topic of a camera making `kinds`, and its type: colour both raw and compressed, as
    image_transport offers it."""
    topics, image = CameraTopics(camera), "sensor_msgs/msg/Image"
    out = {topics.info: "sensor_msgs/msg/CameraInfo"}
    if "rgb" in kinds:
        out |= {topics.colour_raw: image, topics.colour_compressed: "sensor_msgs/msg/CompressedImage"}
    out |= {topics.image(kind): image for kind in kinds if kind != "rgb"}
    return out


def live_messages(message: CameraImage, wanted: set[str], first_of_frame: bool) -> list[tuple[str, object]]:
    """The live topics (of `camera_topic_types`) one camera image feeds, among those `wanted`."""
    topics, out = CameraTopics(message.camera), []
    if message.kind == "rgb":
        if topics.colour_raw in wanted:
            out.append((topics.colour_raw, raw_image_msg(message)))
        if topics.colour_compressed in wanted:
            out.append((topics.colour_compressed, compressed_image_msg(message)))
    elif (topic := topics.image(message.kind)) in wanted:
        out.append((topic, raw_image_msg(message)))
    if first_of_frame and topics.info in wanted:
        out.append((topics.info, camera_info_msg(message)))
    return out


def _header(message: CameraImage):
    return ros_type("std_msgs/msg/Header")(stamp=time_msg(message.sim_time_s), frame_id=optical_frame(message.camera))


def image_msg(message: CameraImage):
    """What a recording holds of an image, however it travelled: colour a `sensor_msgs/CompressedImage` (raw
    arrays packed as PNG here, in the recorder's process, not the sim's loop), else a `sensor_msgs/Image`."""
    if message.kind == "rgb":
        return compressed_image_msg(message)
    return raw_image_msg(message)


def compressed_image_msg(message: CameraImage):
    """`sensor_msgs/CompressedImage` of a colour image: its png or jpeg file as it travelled, or raw packed as png."""
    data = message.data
    if message.encoding == "raw":
        array = decode_image("rgb", data, "raw", message.width_px, message.height_px)
        data, fmt = encode_image("rgb", array, "png"), "png"
    else:
        fmt = message.encoding
    return ros_type("sensor_msgs/msg/CompressedImage")(
        header=_header(message), format=fmt, data=np.frombuffer(data, np.uint8)
    )


def raw_image_msg(message: CameraImage):
    """`sensor_msgs/Image` of any image: rgb8, 16UC1 (depth in millimetres, as depth cameras' drivers publish it,
    whether it travelled as PNG or as metres), 32SC1 (ids)."""
    array = decode_image(message.kind, message.data, message.encoding, message.width_px, message.height_px)
    if message.kind == "depth":  # to the millimetre (the PNG's own); 0 where nothing is seen, 65.535 m at most
        array = np.clip(np.rint(array * 1000.0), 0, 65535).astype("<u2")
    row = array.strides[0]
    return ros_type("sensor_msgs/msg/Image")(
        header=_header(message),
        height=message.height_px,
        width=message.width_px,
        encoding=IMAGE_ENCODINGS[(message.kind, message.encoding)],
        is_bigendian=0,
        step=row,
        data=np.frombuffer(np.ascontiguousarray(array).tobytes(), np.uint8),
    )


def camera_info_msg(message: CameraImage):
    """`sensor_msgs/CameraInfo`: an ideal pinhole (no distortion), K from the frame, P = [K | 0]."""
    k = np.asarray(message.intrinsics, float)
    p = np.zeros((3, 4))
    p[:, :3] = k.reshape(3, 3)
    return ros_type("sensor_msgs/msg/CameraInfo")(
        header=_header(message),
        height=message.height_px,
        width=message.width_px,
        distortion_model="plumb_bob",
        d=np.zeros(5),
        k=k,
        r=np.eye(3).ravel(),
        p=p.ravel(),
        binning_x=0,
        binning_y=0,
        roi=ros_type("sensor_msgs/msg/RegionOfInterest")(x_offset=0, y_offset=0, height=0, width=0, do_rectify=False),
    )


def optical_in_mount(placement: CameraPlacement) -> tuple[np.ndarray, np.ndarray]:
    """A camera's optical frame (+z forward, +x right, +y down) in its mount's frame: position and quaternion
    (x, y, z, w), from its placement (at `xyz`, looking at `look_at`, `up` up in the image)."""
    eye = np.asarray(placement.xyz, float)
    forward = np.asarray(placement.look_at, float) - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, np.asarray(placement.up, float))
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    return eye, Rotation.from_matrix(np.column_stack([right, down, forward])).as_quat()


def camera_static_transforms(scene: Scene) -> list:
    """`/tf_static`: each camera's optical frame under its mount, `world` or its arm's link (`<arm>/<link>`): fixed
    to it, as robot_state_publisher publishes a fixed joint."""
    out = []
    for camera in scene.cameras:
        (x, y, z), (qx, qy, qz, qw) = optical_in_mount(camera.pose)
        transform = ros_type("geometry_msgs/msg/Transform")(
            translation=ros_type("geometry_msgs/msg/Vector3")(x=x, y=y, z=z),
            rotation=ros_type("geometry_msgs/msg/Quaternion")(x=qx, y=qy, z=qz, w=qw),
        )
        parent = WORLD if camera.arm is None else f"{camera.arm}/{camera.link}"
        header = ros_type("std_msgs/msg/Header")(stamp=time_msg(0.0), frame_id=parent)
        out.append(
            ros_type("geometry_msgs/msg/TransformStamped")(
                header=header, child_frame_id=optical_frame(camera.name), transform=transform
            )
        )
    return out


def camera_topics(message: CameraImage, first_of_frame: bool) -> list[tuple[str, Callable[[], object]]]:
    """(topic, maker) for each ROS message one camera image makes; the frame's first image also its camera info
    (its optical frame is on `/tf_static`: `camera_static_transforms`)."""
    out: list[tuple[str, Callable[[], object]]] = [(image_topic(message), lambda: image_msg(message))]
    if first_of_frame:
        out.append((CameraTopics(message.camera).info, lambda: camera_info_msg(message)))
    return out
