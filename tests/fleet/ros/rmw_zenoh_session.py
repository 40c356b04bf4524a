"""A line that serves its ROS 2 topics, services and actions natively (rmw_zenoh's layout) on its own secure
router, used through zenoh-ros2-sdk, an independent pure-Python rmw_zenoh implementation: it computes the type
hashes and key expressions of topics and services itself, from the definitions, sends requests as queries with
its own attachments, and decodes the CDR. For the action's own services (send_goal, get_result, cancel_goal) the
SDK has no action support: its service client is given the types (from the definitions clawfleet ships, whose
hashes `test_ros_interfaces.py` checks against published values)."""

from __future__ import annotations

import os
import re
import threading
import time
from pathlib import Path

import numpy as np
from rosbags.typesys.store import Nodetype

from fleet.record.ros_types import TYPESTORE
from fleet.ros.rmw_zenoh import type_hash
from fleet.ros.ros_interfaces import DEFINITIONS
from fleet.ros.ros_json import from_json
from fleet.run.launcher import Launcher
from robots.registry import get_robot
from tests.fleet.ros.pyzeros_user import use_the_line

DOMAIN = 7
SEPARATOR = "=" * 80 + "\n"
TOPICS = {
    "/joint_states": "sensor_msgs/msg/JointState",
    "/clock": "rosgraph_msgs/msg/Clock",
    "/tf": "tf2_msgs/msg/TFMessage",
}
ACTION = "/arm_1/follow_joint_trajectory"
FJT = "control_msgs/action/FollowJointTrajectory"
STATUS = "action_msgs/msg/GoalStatusArray"


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
    for srv in ("std_srvs/srv/SetBool.srv", "action_msgs/srv/CancelGoal.srv"):  # as the packages ship them, but
        (folder / srv).parent.mkdir(parents=True, exist_ok=True)  # package names spelled out (the SDK reads a
        text = (DEFINITIONS / srv).read_text()  # relative name in a .srv as `<pkg>/srv/<Name>`)
        (folder / srv).write_text(re.sub(r"^GoalInfo", "action_msgs/GoalInfo", text, flags=re.MULTILINE))


def used_types(typename: str, found: dict | None = None) -> dict:
    """A registered type and every type its fields use, as rosbags' field definitions."""
    found = {} if found is None else found
    found[typename] = TYPESTORE.fielddefs[typename]
    for _, (node, detail) in found[typename][1]:
        nested = (
            detail if node == Nodetype.NAME else detail[0][1] if node in (Nodetype.ARRAY, Nodetype.SEQUENCE) else None
        )
        if isinstance(nested, str) and nested not in found:
            used_types(nested, found)
    return found


def uuid(n: int) -> dict:
    return {"uuid": [n] * 16}


class Ros2Listener:
    """Subscribes and drives with the SDK, as a ROS 2 node would, through the run's router with the login of an
    outside ROS 2 stack (`ros_client`), given arm_1 only; what it heard goes into the dict it is given."""

    domain = DOMAIN
    arms = ("arm_1",)

    def __init__(self, definitions: Path) -> None:
        type_hash(FJT + "_SendGoal")  # the action's types registered here (clawfleet's definitions)
        write_definitions(definitions, [*TOPICS.values(), STATUS, "action_msgs/msg/GoalInfo", "tf2_msgs/msg/TFMessage"])
        self.definitions = definitions

    def __call__(self, launcher: Launcher, heard: dict, after: threading.Event) -> None:
        """Listen at once; drive arm_1 once `after` is set (the rosbridge user is done with the line); then a pyzeros
        user (`pyzeros_user`) listens and calls the e-stop too."""
        try:
            self._listen(launcher, heard)
            after.wait(150)
            self._drive(heard)
            config = launcher.bus.config_for("ros_client")
            heard["pyzeros"] = use_the_line(config, launcher.endpoint, DOMAIN)
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
        os.environ["ZENOH_SESSION_CONFIG_URI"] = launcher.bus.config_for("ros_client")
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
        self.router = {"router_ip": host, "router_port": int(port), "domain_id": DOMAIN}

    def _drive(self, heard: dict) -> None:
        """The e-stop service, a late subscriber of a latched topic, and arm_1's trajectory action: a goal to its
        end (feedback, status, result), one with unknown joints, and one cancelled."""
        from zenoh_ros2_sdk import ROS2ServiceClient, ROS2Subscriber
        from zenoh_ros2_sdk.qos import QosDurability, QosProfile
        from zenoh_ros2_sdk.session import ZenohSession

        latched = QosProfile(durability=QosDurability.TRANSIENT_LOCAL, history_depth=1)
        heard["tf_static"] = []
        late = ROS2Subscriber(
            "/tf_static", "tf2_msgs/msg/TFMessage", heard["tf_static"].append, qos=latched, **self.router
        )
        estop = ROS2ServiceClient("/estop", "std_srvs/srv/SetBool", **self.router)
        heard["estop"] = [estop.call(data=True), estop.call(data=False)]
        store = ZenohSession.get_instance().store
        for part in (
            "_SendGoal_Request",
            "_SendGoal_Response",
            "_GetResult_Request",
            "_GetResult_Response",
            "_FeedbackMessage",
        ):
            store.register({k: v for k, v in used_types(FJT + part).items() if k not in store.fielddefs})
        heard["feedback"], heard["status"] = [], []
        sdk = dict(self.router)
        feedback = ROS2Subscriber(
            f"{ACTION}/_action/feedback", FJT + "_FeedbackMessage", heard["feedback"].append,
            msg_definition=f"unique_identifier_msgs/UUID goal_id\n{FJT}_Feedback feedback",
            type_hash=type_hash(FJT + "_FeedbackMessage"), **sdk,
        )  # fmt: skip
        status = ROS2Subscriber(f"{ACTION}/_action/status", STATUS, heard["status"].append, qos=latched, **sdk)
        send_goal = (
            "SendGoal",
            f"unique_identifier_msgs/UUID goal_id\n{FJT}_Goal goal",
            "bool accepted\nbuiltin_interfaces/Time stamp",
        )
        get_result = ("GetResult", "unique_identifier_msgs/UUID goal_id", f"int8 status\n{FJT}_Result result")

        def client(action: str, service: str, part: str, request: str, response: str, timeout_s: float = 20.0):
            """The SDK's service client on one of the action's services, given its types."""
            return ROS2ServiceClient(
                f"{action}/_action/{service}", f"{FJT}_{part}", type_hash=type_hash(f"{FJT}_{part}"), timeout=timeout_s,
                request_definition=request, response_definition=response, **sdk,
            )  # fmt: skip

        send, result = client(ACTION, "send_goal", *send_goal), client(ACTION, "get_result", *get_result)
        cancel = ROS2ServiceClient(f"{ACTION}/_action/cancel_goal", "action_msgs/srv/CancelGoal", **sdk)
        spec = get_robot("openclaw")
        joints, home = list(spec.arm_joints), np.asarray(spec.home_q, float)
        heard["target"] = (home + np.array([0.25, -0.2, 0.2, 0.0, 0.2, 0.0])).tolist()

        def goal(n: int, names: list[str], q: list[float], seconds: int) -> dict:
            point = {"positions": q, "time_from_start": {"sec": seconds, "nanosec": 0}}
            trajectory = {"trajectory": {"joint_names": names, "points": [point]}}
            return {
                "goal_id": from_json("unique_identifier_msgs/msg/UUID", uuid(n)),
                "goal": from_json(FJT + "_Goal", trajectory),
            }

        heard["sent"] = send.call(**goal(1, joints, heard["target"], 2))
        heard["result"] = result.call(goal_id=from_json("unique_identifier_msgs/msg/UUID", uuid(1)))
        heard["unknown_joints"] = send.call(**goal(2, ["elbowz", *joints[1:]], home.tolist(), 1))
        heard["slow"] = send.call(**goal(3, joints, home.tolist(), 5))
        time.sleep(0.5)
        heard["cancel"] = cancel.call(goal_info=from_json("action_msgs/msg/GoalInfo", {"goal_id": uuid(3)}))
        heard["cancelled"] = result.call(goal_id=from_json("unique_identifier_msgs/msg/UUID", uuid(3)))
        not_given = client("/arm_0/follow_joint_trajectory", "send_goal", *send_goal, timeout_s=3.0)
        heard["arm_0"] = not_given.call(**goal(4, joints, home.tolist(), 1))
        for endpoint in (late, estop, feedback, status, send, result, cancel, not_given):
            endpoint.close()
