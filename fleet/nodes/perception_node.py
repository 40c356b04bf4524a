"""The perception process: the parts a running line's fixed cameras show, as tracks, published for each frame
(`PartDetections` on `clawfleet/<run>/perception/<camera>`), and the line's parts as seen (`PartsState` on
`clawfleet/<run>/seen/parts`, `docs/perception.md`). It attaches to the line over the bus, asks the sim for the
scene, and sees only the cameras' colour and depth images and the line's events.

    python -m fleet.nodes.perception_node --run line --connect tcp/127.0.0.1:7447
"""

from __future__ import annotations

import argparse
import sys

import zenoh

from fleet.bus.codec import encode
from fleet.bus.keys import Keys
from fleet.bus.session import BusEndpoints, Inbox, add_bus_arguments, open_session
from fleet.common.processes import StopFlag, write_node_report
from fleet.nodes.attached import line_scene
from fleet.nodes.perception_feed import PerceptionFeed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fleet-perception", description=__doc__.splitlines()[0])
    parser.add_argument("--run", default="line", help="run id of the line to see")
    parser.add_argument("--scene-timeout", type=float, default=15.0, help="seconds to wait for the sim's scene")
    parser.add_argument("--report", help="write the node's figures to this JSON file at exit")
    parser.add_argument("--cameras", default="", help="the fixed cameras the sim renders, by name (default: all)")
    add_bus_arguments(parser)
    args = parser.parse_args(argv)
    stop = StopFlag()
    keys = Keys(args.run)
    with open_session(BusEndpoints.from_args(args)) as session:
        scene = line_scene(session, keys, args.scene_timeout, "fleet perception")
        if scene is None:
            return 1
        cameras = [c.name for c in scene.cameras if c.arm is None]
        if args.cameras and args.cameras != "all":
            cameras = [name for name in cameras if name in args.cameras.split(",")]
        if not cameras:
            print(f"fleet perception: the scene {scene.name} has no fixed camera to see the line with", file=sys.stderr)
            return 1
        block = zenoh.CongestionControl.BLOCK  # never dropped on a busy link: a lockstep line waits for each
        publishers = {
            name: session.declare_publisher(keys.detections(name), congestion_control=block) for name in cameras
        }
        seen_pub = session.declare_publisher(keys.seen_parts, congestion_control=block)
        feed = PerceptionFeed(
            scene,
            cameras,
            lambda camera, msg: publishers[camera].put(encode(msg)),
            lambda msg: seen_pub.put(encode(msg)),
        )
        inbox = Inbox()
        subscribers = [
            session.declare_subscriber(keys.camera(name, kind), inbox) for name in cameras for kind in ("rgb", "depth")
        ]
        subscribers.append(session.declare_subscriber(keys.events, inbox))
        ready = session.declare_publisher(keys.seen_ready)  # said until the line's first image: the sim starts then
        try:
            while not stop.should_stop():
                if not feed.pairs.heard:
                    ready.put(b"")
                inbox.wait(0.05)
                for key, payload in inbox.drain():
                    feed.take(key, payload)
                feed.see()
        finally:
            ready.undeclare()
            for subscriber in subscribers:
                subscriber.undeclare()
            write_node_report(args.report, feed.report() | {"stopped_by": stop.reason})
    return 0


if __name__ == "__main__":
    sys.exit(main())
