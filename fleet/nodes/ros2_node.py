"""The native ROS 2 process: the line's topics, services and actions on its own Zenoh router as rmw_zenoh lays
them out (`fleet.ros.rmw_zenoh`), so ROS 2 nodes on `rmw_zenoh_cpp` connected to the router see and drive the arms
with no bridge (`fleet run --ros2`, `fleet ros2 serve`). It asks the sim for the scene, publishes what the bus
carries, and sends ROS clients' goals, e-stops and pauses over the bus (as `ros`, like rosbridge).

    python -m fleet.nodes.ros2_node --run line --connect tcp/127.0.0.1:7447 --domain-id 0
"""

from __future__ import annotations

import argparse
import os
import sys

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState, CameraImage, GoalResultMsg, LineView
from fleet.bus.session import BusEndpoints, Inbox, open_session
from fleet.common.processes import StopFlag, write_node_report
from fleet.nodes.attached import OnDemandSubscriptions, add_ros_node_arguments, line_scene, ros_line_bus
from fleet.ros import names
from fleet.ros.line_actions import LineActions
from fleet.ros.line_services import LineBus, ServiceError, answer_line_service
from fleet.ros.line_topics import LineTopics
from fleet.ros.rmw_zenoh import Ros2Node
from fleet.ros.ros2_actions import NativeAction
from fleet.ros.ros_json import from_json, to_json
from robots.registry import get_robot
from scenes.schema import IMAGE_KINDS, Scene

NODE_NAME = "clawfleet"
SOURCE = "ros2"
TRAJECTORY = "trajectory_msgs/msg/JointTrajectory"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fleet-ros2", description=__doc__.splitlines()[0])
    parser.add_argument("--domain-id", type=int, default=0, help="ROS_DOMAIN_ID of the topics (0..232)")
    add_ros_node_arguments(parser)
    return parser


class NativeLine:
    """The line as one ROS 2 node: its topics from the bus, its services, actions and trajectory topics to it."""

    def __init__(
        self,
        session,
        keys: Keys,
        scene: Scene,
        domain_id: int,
        bus: LineBus,
        max_rate_hz: float = names.DEFAULT_MAX_RATE_HZ,
    ) -> None:
        self.inbox = Inbox()
        wake = self.inbox.wake
        self.node = Ros2Node(session, domain_id, NODE_NAME)
        self.topics = LineTopics(scene, max_rate_hz)
        self.pubs = {t: self.node.publisher(t, ty, latched=t in names.LATCHED) for t, ty in self.topics.types.items()}
        self.bus = bus
        self.actions = LineActions({a.name: get_robot(a.model) for a in scene.arms}, bus.send_goal)
        self.native = [
            NativeAction(self.node, action, kind, self.actions, wake)
            for action, kind in names.line_actions(self.topics.arms).items()
        ]
        self.services = {n: self.node.service(n, ty, wake) for n, ty in names.SERVICE_TYPES.items()}
        self.commands = {
            a: self.node.subscription(f"/{a}/joint_trajectory", TRAJECTORY, wake) for a in self.topics.arms
        }
        self.drops = DropCounter()
        self.decoders = {
            "state": Decoder(ArmState, self.drops),
            "result": Decoder(GoalResultMsg, self.drops),
            "view": Decoder(LineView, self.drops),
        } | {kind: Decoder(CameraImage, self.drops) for kind in IMAGE_KINDS}
        self.keys = keys
        self.results = session.declare_subscriber(keys.all_arms("result"), self.inbox)  # few: one per goal
        self.listened = OnDemandSubscriptions(session, self.inbox)
        self.sent = self.refused = 0

    def serve(self, stop: StopFlag) -> None:
        for topic, msg in self.topics.latched.items():  # said once: their publishers keep them for late joiners
            self.pubs[topic].put(msg)
        while not stop.should_stop():
            heard = {t for t, pub in self.pubs.items() if pub.heard}  # only the topics someone subscribes to are built
            self._from_bus(heard)
            self._put(self.topics.held_back(heard))
            self._answer_services()
            self._take_commands()
            for action in self.native:
                action.poll(max(self.topics.clock_s, 0.0))
            self.listened.want(self.topics.keys_needed(self.keys, heard, self.actions.arms_in_flight()))
            self.inbox.wait(0.05)

    def _from_bus(self, wanted: set[str]) -> None:
        for key, payload in self.inbox.drain():
            decoder = self.decoders.get(key.rsplit("/", 1)[-1])
            msg = decoder.decode(key, payload) if decoder else None
            if isinstance(msg, ArmState):
                self.actions.on_state(msg)
                continue
            if isinstance(msg, GoalResultMsg):
                self.actions.on_result(msg)
                out = self.topics.from_result(msg, wanted)
            elif isinstance(msg, LineView):
                out = self.topics.from_view(msg, wanted)
            elif isinstance(msg, CameraImage):
                out = self.topics.from_camera(msg, wanted)
            else:
                continue
            self._put(out)

    def _put(self, out: list[tuple[str, object]]) -> None:
        for topic, ros_msg in out:
            self.pubs[topic].put(ros_msg)
            self.sent += 1

    def _answer_services(self) -> None:
        for name, service in self.services.items():
            for request in service.take():
                try:
                    values = answer_line_service(name, to_json(request.message), self.bus)
                except ServiceError as exc:
                    self.refused += 1
                    values = {"success": False, "message": str(exc)}
                request.reply(from_json(service.response_type, values))

    def _take_commands(self) -> None:
        """`/<arm>/joint_trajectory`: fire-and-forget goals; one that cannot be read is counted."""
        for arm, sub in self.commands.items():
            for msg in sub.take():
                try:
                    self.actions.send_trajectory(arm, to_json(msg))
                except ValueError:
                    self.refused += 1

    def figures(self) -> dict:
        unreadable = sum(x.unreadable for x in [*self.native, *self.services.values(), *self.commands.values()])
        return {
            "messages_sent": self.sent,
            "goals_sent": self.actions.sent,
            "goals_refused": sum(a.refused for a in self.native),
            "requests_refused": self.refused,
            "requests_unreadable": unreadable,
            "dropped_messages": self.drops.total,
            "refused_messages": self.drops.kinds(),
        }

    def close(self) -> None:
        self.results.undeclare()
        self.listened.close()
        for action in self.native:
            action.close()
        self.node.close()


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not 0 <= args.domain_id <= 232:
        print(f"fleet ros2: --domain-id {args.domain_id}: ROS domains are 0..232", file=sys.stderr)
        return 2
    stop = StopFlag()
    if args.nice:
        os.nice(args.nice)
    keys = Keys(args.run)
    with open_session(BusEndpoints.from_args(args)) as session:
        scene = line_scene(session, keys, args.scene_timeout, "fleet ros2")
        if scene is None:
            return 1
        bus = ros_line_bus(session, keys, [a.name for a in scene.arms], SOURCE)
        line = NativeLine(session, keys, scene, args.domain_id, bus, args.max_rate_hz)
        try:
            line.serve(stop)
        finally:
            line.close()
            write_node_report(args.report, line.figures() | {"stopped_by": stop.reason})
    return 0


if __name__ == "__main__":
    sys.exit(main())
