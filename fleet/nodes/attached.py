"""What the nodes that attach to a running line over the bus (monitor, rosbridge, the ROS 2 node) share: the
line's scene, asked of its sim, or one line saying why there is none; the ROS front ends' publishers."""

from __future__ import annotations

import sys

import zenoh

from fleet.bus.codec import encode
from fleet.bus.keys import Keys
from fleet.bus.messages import EStop, SimControl
from fleet.bus.scene_query import SceneUnavailable, fetch_scene
from fleet.ros.line_services import LineBus
from scenes.schema import Scene


def line_scene(session: zenoh.Session, keys: Keys, timeout_s: float, prog: str) -> Scene | None:
    """The scene the line's sim serves; None after printing `prog: why` when no sim answered in `timeout_s`."""
    try:
        return fetch_scene(session, keys, timeout_s)
    except SceneUnavailable as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return None


def ros_line_bus(session: zenoh.Session, keys: Keys, arms: list[str], source: str) -> LineBus:
    """What a ROS front end may do to the line: outside goals to each arm (on its `drive` key: they take the
    arm), the e-stop, pause and resume, said as coming from `source`."""
    goals = {a: session.declare_publisher(keys.arm_drive(a)) for a in arms}
    estop, control = session.declare_publisher(keys.estop), session.declare_publisher(keys.control)
    return LineBus(
        send_goal=lambda msg: goals[msg.arm].put(encode(msg)),
        estop=lambda engaged: estop.put(encode(EStop(engaged, source))),
        pause=lambda paused: control.put(encode(SimControl(source, paused=paused))),
    )
