"""ROS 2 services and actions in the recordings' typestore (`fleet.record.ros_types.TYPESTORE`), so rmw_zenoh's
front end serialises them with rosbags and names them by their RIHS01 hashes.

rosbags carries messages only. Services and actions are registered here as rosidl generates them: a service
`pkg/srv/Name` is `Name_Request`, `Name_Response`, `Name_Event` and `Name` itself (request_message,
response_message, event_message: the type its hash is taken over); an action adds `Name_Goal`, `Name_Result`,
`Name_Feedback`, the `Name_SendGoal` and `Name_GetResult` services and `Name_FeedbackMessage`. The definitions
rosbags lacks are data in `definitions/` (control_msgs, std_srvs, action_msgs' CancelGoal; their licences there).
"""

from __future__ import annotations

import re
from functools import cache
from pathlib import Path

from rosbags.typesys import get_types_from_msg
from rosbags.typesys.store import Nodetype

from fleet.record.ros_types import TYPESTORE

DEFINITIONS = Path(__file__).with_name("definitions")
SEPARATOR = re.compile(r"^---\s*$", re.MULTILINE)
SERVICES = ("std_srvs/srv/SetBool", "std_srvs/srv/Trigger", "action_msgs/srv/CancelGoal")
ACTIONS = ("control_msgs/action/FollowJointTrajectory", "control_msgs/action/GripperCommand")
MESSAGES = (
    "control_msgs/msg/JointTolerance",
    "control_msgs/msg/JointComponentTolerance",
    "control_msgs/msg/GripperCommand",
)


def _plain(value: object) -> object:
    """rosbags files `pkg/srv/Name` under `pkg/srv/msg/Name`; rosidl (and the hashes) keep `pkg/srv/Name`. A
    relative name in a `.srv` or `.action` (`GoalInfo`) is the package's message (`pkg/msg/GoalInfo`)."""
    if isinstance(value, str):
        name = value.replace("/srv/msg/", "/srv/").replace("/action/msg/", "/action/")
        package, kind, short = (name.split("/") + ["", ""])[:3]
        if kind in ("srv", "action") and name not in TYPESTORE.fielddefs:
            return f"{package}/msg/{short}"
        return name
    if isinstance(value, (list, tuple)):
        return type(value)(_plain(v) for v in value)
    return value


def _register(text: str, typename: str) -> None:
    if typename not in TYPESTORE.fielddefs:
        (definition,) = get_types_from_msg(text, typename).values()
        TYPESTORE.register({typename: _plain(definition)})


def _sections(typename: str) -> list[str]:
    suffix = typename.split("/")[1]
    return SEPARATOR.split((DEFINITIONS / f"{typename}.{suffix}").read_text())


def register_service(srv: str, request: str, response: str) -> None:
    """A service from its request and response text, as rosidl builds it from a `.srv`."""
    _register(request, f"{srv}_Request")
    _register(response, f"{srv}_Response")
    event = f"service_msgs/msg/ServiceEventInfo info\n{srv}_Request[<=1] request\n{srv}_Response[<=1] response"
    _register(event, f"{srv}_Event")
    _register(f"{srv}_Request request_message\n{srv}_Response response_message\n{srv}_Event event_message", srv)


def register_action(action: str, goal: str, result: str, feedback: str) -> None:
    """An action from its goal, result and feedback text, as rosidl builds it from an `.action`."""
    for text, part in ((goal, "Goal"), (result, "Result"), (feedback, "Feedback")):
        _register(text, f"{action}_{part}")
    uuid = "unique_identifier_msgs/UUID goal_id"
    register_service(
        f"{action}_SendGoal", f"{uuid}\n{action}_Goal goal", "bool accepted\nbuiltin_interfaces/Time stamp"
    )
    register_service(f"{action}_GetResult", uuid, f"int8 status\n{action}_Result result")
    _register(f"{uuid}\n{action}_Feedback feedback", f"{action}_FeedbackMessage")


def _event_info_as_rosidl_hashes_it() -> None:
    """rosidl reads a `.msg`'s `char` as uint8 (its IDL has no char) and hashes it so; rosbags keeps `char`. The
    one such field services need is ServiceEventInfo's `client_gid` (same bytes on the wire either way)."""
    name = "service_msgs/msg/ServiceEventInfo"
    consts, fields = TYPESTORE.fielddefs[name]
    char16 = (Nodetype.ARRAY, ((Nodetype.BASE, ("char", 0)), 16))
    uint8x16 = (Nodetype.ARRAY, ((Nodetype.BASE, ("uint8", 0)), 16))
    TYPESTORE.fielddefs[name] = (consts, [(n, uint8x16 if d == char16 else d) for n, d in fields])


@cache
def register_interfaces() -> None:
    """Register every service and action a line serves (once per process)."""
    _event_info_as_rosidl_hashes_it()
    for msg in MESSAGES:
        _register((DEFINITIONS / f"{msg}.msg").read_text(), msg)
    for srv in SERVICES:
        request, response = _sections(srv)
        register_service(srv, request, response)
    for action in ACTIONS:
        register_action(action, *_sections(action))
