"""The native ROS 2 process: the line's topics on its own Zenoh router as rmw_zenoh lays them out
(`fleet.ros.rmw_zenoh`), so ROS 2 nodes on `rmw_zenoh_cpp` connected to the router see the arms with no bridge
(`fleet run --ros2`, `fleet ros2`). It asks the sim for the scene, then publishes what the bus carries.

    python -m fleet.nodes.ros2_node --run line --connect tcp/127.0.0.1:7447 --domain-id 0
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState, PartsState
from fleet.bus.session import BusEndpoints, Inbox, add_bus_arguments, open_session
from fleet.common.processes import StopFlag, write_report
from fleet.nodes.attached import line_scene
from fleet.ros import names
from fleet.ros.line_topics import LineTopics
from fleet.ros.rmw_zenoh import Ros2Node

NODE_NAME = "clawfleet"
LATCHED_EVERY_S = 1.0  # latched topics are said again this often (wall): a late joiner has them within it


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fleet-ros2", description=__doc__.splitlines()[0])
    parser.add_argument("--run", default="line", help="run id of the line to serve")
    parser.add_argument("--domain-id", type=int, default=0, help="ROS_DOMAIN_ID of the topics (0..232)")
    parser.add_argument("--scene-timeout", type=float, default=15.0, help="seconds to wait for the sim's scene")
    parser.add_argument("--nice", type=int, default=10, help="scheduling niceness: the line comes first (default 10)")
    parser.add_argument("--report", help="write the node's figures to this JSON file at exit")
    add_bus_arguments(parser)
    return parser


def serve(session, keys: Keys, topics: LineTopics, domain_id: int, stop: StopFlag) -> dict:
    """Publish the line's topics until told to stop; how many messages went out."""
    node = Ros2Node(session, domain_id, NODE_NAME)
    pubs = {t: node.publisher(t, ty, latched=t in names.LATCHED) for t, ty in topics.types.items()}
    drops, inbox = DropCounter(), Inbox()
    decoders = {"state": Decoder(ArmState, drops), "parts": Decoder(PartsState, drops)}
    subs = [session.declare_subscriber(k, inbox) for k in (keys.all_arms("state"), keys.parts)]
    wanted, sent, latched_at = set(topics.types), 0, 0.0
    try:
        while not stop.should_stop():
            if time.monotonic() - latched_at >= LATCHED_EVERY_S:
                latched_at = time.monotonic()
                for topic, msg in topics.latched.items():
                    pubs[topic].put(msg)
            for key, payload in inbox.drain():
                leaf = key.rsplit("/", 1)[-1]
                msg = decoders[leaf].decode(key, payload) if leaf in decoders else None
                if isinstance(msg, ArmState):
                    out = topics.from_state(msg, wanted)
                elif isinstance(msg, PartsState):
                    out = topics.from_parts(msg, wanted)
                else:
                    continue
                for topic, ros_msg in out:
                    pubs[topic].put(ros_msg)
                    sent += 1
            inbox.wait(0.05)
    finally:
        for sub in subs:
            sub.undeclare()
        node.close()
    return {"messages_sent": sent, "dropped_messages": drops.total, "refused_messages": drops.kinds()}


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
        figures = serve(session, keys, LineTopics(scene), args.domain_id, stop)
        write_report(args.report, figures | {"stopped_by": stop.reason})
    return 0


if __name__ == "__main__":
    sys.exit(main())
