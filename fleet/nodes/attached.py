"""What the nodes that attach to a running line over the bus (monitor, rosbridge, the ROS 2 node) share: the
line's scene, asked of its sim, or one line saying why there is none; the ROS front ends' publishers."""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable

import zenoh

from fleet.bus.codec import encode
from fleet.bus.keys import Keys
from fleet.bus.messages import EStop, SimControl
from fleet.bus.scene_query import SceneUnavailable, fetch_scene
from fleet.bus.session import add_bus_arguments
from fleet.ros.line_services import LineBus
from fleet.ros.names import DEFAULT_MAX_RATE_HZ
from scenes.schema import Scene

ROS_NICENESS = 10  # what ROS tools watch must not slow the line down (as the monitor)


def add_rate_argument(parser: argparse.ArgumentParser, flag: str = "--max-rate-hz") -> None:
    """The ROS front ends' cap on topics from the line's view and states, in wall Hz (`fleet.ros.line_topics`)."""
    parser.add_argument(
        flag,
        type=float,
        default=DEFAULT_MAX_RATE_HZ,
        metavar="HZ",
        help=f"ROS topics from the line's view and states at most this often in wall time (0: every one; default "
        f"{DEFAULT_MAX_RATE_HZ:g}); a lockstep line runs many times faster than ROS tools draw",
    )


def add_ros_node_arguments(parser: argparse.ArgumentParser) -> None:
    """What both ROS front ends' processes take: the run, how long to wait for its scene, their niceness, the
    topics' rate cap, the report, and the bus."""
    parser.add_argument("--run", default="line", help="run id of the line to serve")
    parser.add_argument("--scene-timeout", type=float, default=15.0, help="seconds to wait for the sim's scene")
    parser.add_argument(
        "--nice",
        type=int,
        default=ROS_NICENESS,
        help=f"scheduling niceness: a front end for ROS tools yields the CPU to the line (default {ROS_NICENESS})",
    )
    add_rate_argument(parser)
    parser.add_argument("--report", help="write the node's figures to this JSON file at exit")
    add_bus_arguments(parser)


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


class OnDemandSubscriptions:
    """The keys a ROS front end listens to only while it needs them: each arm's states (a goal of its clients in
    flight on the arm, a client of that arm's own joint states) and the line's view (clients of the topics it
    feeds). States come at every arm's control rate and views many times a second: a front end hearing them all,
    whether anyone asked or not, costs a lockstep line a fifth of its speed in the router's deliveries alone. A key
    no longer needed is let go after `LINGER_S`."""

    LINGER_S = 2.0

    def __init__(self, session: zenoh.Session, handler: Callable[[zenoh.Sample], None]) -> None:
        self.session, self.handler = session, handler
        self._subs: dict[str, zenoh.Subscriber] = {}
        self._needed_at: dict[str, float] = {}

    def want(self, keys: set[str]) -> None:
        """Listen to exactly these keys from now on (and, for `LINGER_S`, to those just let go)."""
        now = time.monotonic()
        for key in keys:
            self._needed_at[key] = now
            if key not in self._subs:
                self._subs[key] = self.session.declare_subscriber(key, self.handler)
        for key in [k for k in self._subs if k not in keys and now - self._needed_at[k] > self.LINGER_S]:
            self._subs.pop(key).undeclare()

    def close(self) -> None:
        for sub in self._subs.values():
            sub.undeclare()
        self._subs.clear()
