"""The `rosapi` services rosbridge clients use to look around (roslibpy's `get_topics`, roslibjs, Foxglove):
topics, services, action servers and their types, message definitions, nodes, and the time (sim time)."""

from __future__ import annotations

from collections.abc import Callable

from fleet.ros import names
from fleet.ros.line_services import ServiceError
from fleet.ros.ros_json import time_json
from fleet.ros.rosapi_types import full_text, message_details

NODE = "/clawfleet_rosbridge"
LINE = "/clawfleet"  # the line's own processes, named under it: they speak the line's bus, not ROS


def line_nodes(arms: list[str]) -> list[str]:
    """The line's processes as ROS names: the sim, the coordinator and each arm's controller."""
    return [f"{LINE}/sim_server", f"{LINE}/coordinator", *(f"{LINE}/{a}" for a in arms)]


class Rosapi:
    """Answers `/rosapi/*` calls for one line's names; `now_s` gives the line's sim time."""

    def __init__(self, arms: list[str], now_s: Callable[[], float], topics: dict[str, str] | None = None) -> None:
        served = names.line_topics(arms) if topics is None else topics  # the line's topics (its cameras' too)
        self.topics = served | {f"/{a}/joint_trajectory": "trajectory_msgs/msg/JointTrajectory" for a in arms}
        self.actions = names.line_actions(arms)
        self.services = {**names.SERVICE_TYPES, **{s: f"rosapi_msgs/srv/{t}" for s, t in SERVICES.items()}}
        self.now_s = now_s
        self.nodes = [NODE, *line_nodes(arms)]

    def answer(self, service: str, args: dict) -> dict:
        """The response's values; KeyError for a service this is not."""
        name = service.rsplit("/", 1)[-1]
        if name == "topics":
            return {"topics": list(self.topics), "types": list(self.topics.values())}
        if name == "topics_and_raw_types":
            types = list(self.topics.values())
            return {"topics": list(self.topics), "types": types, "typedefs_full_text": [full_text(t) for t in types]}
        if name == "message_details":
            kind = str(args.get("type", ""))
            try:
                return {"typedefs": message_details(kind)}
            except KeyError:
                raise ServiceError(f"message_details: no message type {kind!r} on this line") from None
        if name == "topic_type":
            return {"type": self.topics.get(str(args.get("topic", "")), "")}
        if name == "topics_for_type":
            return {"topics": [t for t, ty in self.topics.items() if ty == args.get("type")]}
        if name == "services":
            return {"services": list(self.services)}
        if name == "service_type":
            return {"type": self.services.get(str(args.get("service", "")), "")}
        if name == "action_servers":
            return {"action_servers": list(self.actions)}
        if name == "nodes":
            return {"nodes": list(self.nodes)}
        if name == "node_details":
            return self._node_details(str(args.get("node", "")))
        if name == "get_time":
            return {"time": time_json(self.now_s())}
        raise KeyError(service)

    def _node_details(self, node: str) -> dict:
        """What a node publishes, subscribes to and serves: the node serving ROS all of the line's topics and
        services, the line's own processes none (`ServiceError` for a node the line has not)."""
        if node not in self.nodes:
            raise ServiceError(f"node_details: no node {node!r} (nodes: {', '.join(self.nodes)})")
        if node != NODE:
            return {"publishing": [], "subscribing": [], "services": []}
        taken = [t for t, kind in self.topics.items() if kind == "trajectory_msgs/msg/JointTrajectory"]
        return {
            "publishing": [t for t in self.topics if t not in taken],
            "subscribing": taken,
            "services": list(self.services),
        }


SERVICES = {
    "/rosapi/topics": "Topics",
    "/rosapi/topics_and_raw_types": "TopicsAndRawTypes",
    "/rosapi/message_details": "MessageDetails",
    "/rosapi/topic_type": "TopicType",
    "/rosapi/topics_for_type": "TopicsForType",
    "/rosapi/services": "Services",
    "/rosapi/service_type": "ServiceType",
    "/rosapi/action_servers": "GetActionServers",
    "/rosapi/nodes": "Nodes",
    "/rosapi/node_details": "NodeDetails",
    "/rosapi/get_time": "GetTime",
}
