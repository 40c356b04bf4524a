"""A line's cameras live on ROS, read by clients clawfleet did not write: roslibpy over rosbridge (colour as a PNG
`CompressedImage` and a raw `Image`, depth, `CameraInfo`) and zenoh-ros2-sdk over rmw_zenoh (which derives the
keys and hashes from the definitions itself)."""

import base64
import io
import multiprocessing
import os
import threading
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest
import roslibpy
from PIL import Image

from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.ros.rmw_zenoh_session import write_definitions
from tests.fleet.ros.rosbridge_session import rosbridge_port
from tests.fleet.test_run import assert_nothing_left

pytestmark = pytest.mark.slow  # a whole realtime line

DOMAIN = 9
ROSLIBPY_TOPICS = {
    "/overhead/image_raw/compressed": "sensor_msgs/msg/CompressedImage",
    "/overhead/image_raw": "sensor_msgs/msg/Image",
    "/overhead/depth/image_raw": "sensor_msgs/msg/Image",
    "/overhead/camera_info": "sensor_msgs/msg/CameraInfo",
}
NATIVE_TOPICS = {"/overhead/image_raw": "sensor_msgs/msg/Image", "/overhead/camera_info": "sensor_msgs/msg/CameraInfo"}


def until(done, timeout_s: float = 40.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not done() and time.monotonic() < deadline:
        time.sleep(0.1)


def with_roslibpy(launcher: Launcher, heard: dict) -> None:
    ros = roslibpy.Ros(host="127.0.0.1", port=rosbridge_port(launcher))
    ros.run(timeout=20)
    try:
        topics = [roslibpy.Topic(ros, name, kind) for name, kind in ROSLIBPY_TOPICS.items()]
        for topic in topics:
            heard[topic.name] = []
            topic.subscribe(heard[topic.name].append)
        until(lambda: all(len(heard[t]) >= 2 for t in ROSLIBPY_TOPICS))
        for topic in topics:
            topic.unsubscribe()
    finally:
        ros.close()  # not terminate(): that stops the process's one Twisted reactor, which other tests reuse


def native_sight(endpoint: str, config: str, definitions: str) -> dict:
    """What a zenoh-ros2-sdk subscriber hears of the camera's image and camera info, as plain values. Runs in a fresh
    process: the SDK keeps one session and one registry a process, which other tests' lines have used."""
    from zenoh_ros2_sdk import ROS2Subscriber
    from zenoh_ros2_sdk.message_registry import get_registry

    write_definitions(get_registry(definitions).messages_dir, list(NATIVE_TOPICS.values()))
    host, port = endpoint.split("/", 1)[1].rsplit(":", 1)
    os.environ["ZENOH_SESSION_CONFIG_URI"] = config
    os.environ["ZENOH_CONFIG_OVERRIDE"] = f'connect/endpoints=["{endpoint}"];listen/endpoints=[]'
    heard: dict = {topic: [] for topic in NATIVE_TOPICS}
    subs = [
        ROS2Subscriber(topic, kind, heard[topic].append, domain_id=DOMAIN, router_ip=host, router_port=int(port))
        for topic, kind in NATIVE_TOPICS.items()
    ]
    until(lambda: all(heard[t] for t in NATIVE_TOPICS))
    for sub in subs:
        sub.close()
    image, info = heard["/overhead/image_raw"][-1], heard["/overhead/camera_info"][-1]
    return {
        "image": (image.encoding, image.width, image.height, bytes(np.asarray(image.data, np.uint8))),
        "info": (info.header.frame_id, list(info.k)),
    }


def with_zenoh_ros2_sdk(launcher: Launcher, heard: dict, definitions) -> None:
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        config = launcher.bus.config_for("ros_client")
        heard |= pool.submit(native_sight, launcher.endpoint, str(config), str(definitions)).result(timeout=120)


@pytest.fixture(scope="module")
def heard(tmp_path_factory):
    """pick_cell's overhead camera rendered in a realtime line with rosbridge and the native ROS 2 graph; what each
    client heard."""
    options = RunOptions(
        scene="pick_cell", duration_s=120.0, mode="realtime", cameras="overhead", rosbridge_port=0, ros2_domain=DOMAIN
    )
    out: dict = {"roslibpy": {}, "sdk": {}}
    definitions = tmp_path_factory.mktemp("definitions")
    with Launcher(options) as launcher:

        def clients() -> None:
            try:
                until(lambda: launcher.endpoint is not None)
                with_roslibpy(launcher, out["roslibpy"])
                with_zenoh_ros2_sdk(launcher, out["sdk"], definitions)
            except Exception as exc:
                out["error"] = repr(exc)
            finally:
                launcher.interrupted = "the ROS clients are done"

        user = threading.Thread(target=clients, daemon=True)
        user.start()
        summary = launcher.run()
        user.join(30)
    assert_nothing_left(summary, launcher.endpoint)
    assert "error" not in out, out["error"]
    return out


def test_roslibpy_reads_the_overhead_camera_as_png_raw_and_depth(heard):
    seen = heard["roslibpy"]
    compressed = seen["/overhead/image_raw/compressed"][-1]
    assert compressed["format"] == "png" and compressed["header"]["frame_id"] == "overhead_optical_frame"
    picture = np.asarray(Image.open(io.BytesIO(base64.b64decode(compressed["data"]))))
    assert picture.shape == (120, 160, 3) and picture.std() > 10
    raw = seen["/overhead/image_raw"][-1]
    assert (raw["encoding"], raw["width"], raw["height"], raw["step"]) == ("rgb8", 160, 120, 480)
    assert len(base64.b64decode(raw["data"])) == 160 * 120 * 3
    depth = seen["/overhead/depth/image_raw"][-1]
    millimetres = np.frombuffer(base64.b64decode(depth["data"]), "<u2").reshape(120, 160)
    assert depth["encoding"] == "16UC1" and 500 < np.median(millimetres) < 1000  # the floor, 0.95 m below
    info = seen["/overhead/camera_info"][-1]
    assert (info["width"], info["height"]) == (160, 120) and info["k"][2] == 80.0 and info["k"][5] == 60.0


def test_a_native_ros2_client_reads_the_image_and_camera_info(heard):
    encoding, width, height, data = heard["sdk"]["image"]
    assert (encoding, width, height) == ("rgb8", 160, 120)
    assert np.frombuffer(data, np.uint8).reshape(120, 160, 3).std() > 10
    frame_id, k = heard["sdk"]["info"]
    assert frame_id == "overhead_optical_frame" and k[0] > 0
