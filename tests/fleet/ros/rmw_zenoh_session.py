"""A line that publishes its ROS 2 topics natively (rmw_zenoh's layout) on its own secure router, heard by
zenoh-ros2-sdk, an independent pure-Python rmw_zenoh implementation: it computes the type hashes and key
expressions itself, from the message definitions, and decodes the CDR."""

from __future__ import annotations

import os
import time
from pathlib import Path

from fleet.record.ros_types import TYPESTORE
from fleet.run.launcher import Launcher

DOMAIN = 7
SEPARATOR = "=" * 80 + "\n"
TOPICS = {
    "/joint_states": "sensor_msgs/msg/JointState",
    "/clock": "rosgraph_msgs/msg/Clock",
    "/tf": "tf2_msgs/msg/TFMessage",
}


def write_definitions(folder: Path, typenames: list[str]) -> None:
    """The ROS message definitions (ROS 2 Jazzy's, as rosbags carries them) as `<pkg>/msg/<Name>.msg` files, the
    layout the SDK reads its definitions from (it would fetch them with git otherwise)."""
    for typename in typenames:
        text = TYPESTORE.generate_msgdef(typename, ros_version=2)[0]
        sections = [(typename, text.split(SEPARATOR)[0])]
        for part in text.split(SEPARATOR)[1:]:
            header, _, body = part.partition("\n")
            sections.append((header.removeprefix("MSG: ").strip(), body))
        for name, body in sections:
            package, kind, short = name.split("/") if name.count("/") == 2 else (*name.split("/"), None)
            if short is None:  # `pkg/Name` as MCAP schemas name dependencies
                package, short, kind = name.split("/")[0], name.split("/")[1], "msg"
            path = folder / package / kind / f"{short}.msg"
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(body.strip() + "\n")


class Ros2Listener:
    """Subscribes with the SDK, as a ROS 2 node would, through the run's router with the monitor's login; what it
    heard goes into the dict it is given."""

    domain = DOMAIN

    def __init__(self, definitions: Path) -> None:
        write_definitions(definitions, list(TOPICS.values()))
        self.definitions = definitions

    def __call__(self, launcher: Launcher, heard: dict) -> None:
        try:
            self._listen(launcher, heard)
        except Exception as exc:
            heard["error"] = repr(exc)
        finally:
            for name in ("ZENOH_SESSION_CONFIG_URI", "ZENOH_CONFIG_OVERRIDE"):  # nothing else here reads them
                os.environ.pop(name, None)

    def _listen(self, launcher: Launcher, heard: dict) -> None:
        from zenoh_ros2_sdk import ROS2Subscriber, get_topic_names_and_types
        from zenoh_ros2_sdk.message_registry import get_registry

        deadline = time.monotonic() + 60
        while launcher.endpoint is None and time.monotonic() < deadline:
            time.sleep(0.1)
        endpoint = launcher.endpoint  # tls/127.0.0.1:PORT
        host, port = endpoint.split("/", 1)[1].rsplit(":", 1)
        os.environ["ZENOH_SESSION_CONFIG_URI"] = launcher.bus.config_for("monitor")
        os.environ["ZENOH_CONFIG_OVERRIDE"] = f'connect/endpoints=["{endpoint}"];listen/endpoints=[]'
        get_registry(str(self.definitions))
        subs = []
        for topic, typename in TOPICS.items():
            heard[topic] = []
            subs.append(
                ROS2Subscriber(
                    topic, typename, heard[topic].append, domain_id=DOMAIN, router_ip=host, router_port=int(port)
                )  # fmt: skip
            )
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and not all(heard[t] for t in TOPICS):
            time.sleep(0.1)
        heard["keys"] = {t: s.keyexpr for t, s in zip(TOPICS, subs)}
        heard["graph"] = dict(get_topic_names_and_types(domain_id=DOMAIN, router_ip=host, router_port=int(port)))
        for s in subs:
            s.close()
