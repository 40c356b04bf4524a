"""The Foxglove process: a Foxglove WebSocket server (`fleet.foxglove.line_server`) attached to a running line over
the bus (`fleet foxglove`, `fleet run --foxglove`). It asks the sim for the scene, serves the line's topics to the
Foxglove app at sim time, and sends its e-stops and pauses over the bus. Loopback only: the protocol has no login.

    python -m fleet.nodes.foxglove_node --run line --connect tcp/127.0.0.1:7447 --port 8765
"""

from __future__ import annotations

import argparse
import os
import sys
import threading

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import CameraImage, GoalResultMsg, LineView, SimStatus
from fleet.bus.session import BusEndpoints, Inbox, is_loopback_host, open_session
from fleet.common.processes import StopFlag, write_node_report, write_text_atomically
from fleet.foxglove.line_server import FoxgloveLine
from fleet.foxglove.playback import RecordingPlayback
from fleet.nodes.attached import OnDemandSubscriptions, add_ros_node_arguments, line_scene, ros_line_bus
from fleet.record.replay import Player
from scenes.schema import IMAGE_KINDS

SOURCE = "foxglove"
DEFAULT_PORT = 8765  # the Foxglove app's default for a WebSocket connection


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fleet-foxglove", description=__doc__.splitlines()[0])
    parser.add_argument("--host", default="127.0.0.1", help="loopback address to listen on")
    parser.add_argument("--port", type=int, default=DEFAULT_PORT, help="WebSocket port (0: any free one)")
    parser.add_argument("--url-file", help="write the server's ws:// URL to this file once it listens")
    add_ros_node_arguments(parser)
    return parser


class FoxgloveFeed:
    """What the bus carries, as the Foxglove server's messages: views, goal results, camera images and the sim's
    status, decoded (a malformed one dropped and counted) and handed to `FoxgloveLine`."""

    def __init__(self, line: FoxgloveLine) -> None:
        self.line = line
        self.drops = DropCounter()
        self.decoders = {
            "view": Decoder(LineView, self.drops),
            "result": Decoder(GoalResultMsg, self.drops),
            "status": Decoder(SimStatus, self.drops),
        } | {kind: Decoder(CameraImage, self.drops) for kind in IMAGE_KINDS}

    def take(self, key: str, payload: bytes) -> None:
        decoder = self.decoders.get(key.rsplit("/", 1)[-1])
        msg = decoder.decode(key, payload) if decoder else None
        line = self.line
        if isinstance(msg, LineView):
            line.on_view(msg)
        elif isinstance(msg, GoalResultMsg):
            line.publish(line.topics.from_result(msg, line.wanted()))
        elif isinstance(msg, CameraImage):
            line.publish(line.topics.from_camera(msg, line.wanted()))
        elif isinstance(msg, SimStatus):
            line.on_status(msg)


def serve(feed: FoxgloveFeed, session, keys: Keys, stop: StopFlag) -> None:
    """Until stopped: the bus's messages onto the server (zenoh's callbacks only queue), the keys listened to
    following what the app subscribes to."""
    line, inbox = feed.line, Inbox()
    fixed = [session.declare_subscriber(k, inbox) for k in (keys.all_arms("result"), keys.sim_status)]
    listened = OnDemandSubscriptions(session, inbox)
    try:
        while not stop.should_stop():
            for key, payload in inbox.drain():
                feed.take(key, payload)
            line.publish_latched()
            wanted = line.wanted()
            line.publish(line.topics.held_back(wanted))
            line.tick_clock()
            listened.want(line.topics.keys_needed(keys, wanted, set()))
            inbox.wait(0.05)
    finally:
        listened.close()
        for sub in fixed:
            sub.undeclare()


def serve_recording(player: Player, session, keys: Keys, host: str, port: int, stop: StopFlag) -> str:
    """`fleet replay FILE --foxglove`: the recording played onto the bus (`player`) and served to Foxglove with
    the app's playback controls, until stopped; why it could not listen ("" when it served)."""
    playback = RecordingPlayback(player)
    bus = ros_line_bus(session, keys, [a.name for a in player.recording.scene.arms], SOURCE)
    line = FoxgloveLine(player.recording.scene, bus, playback=playback)
    try:
        served = line.start(host, port)
    except RuntimeError as exc:
        return f"cannot listen on {host}:{port}: {exc}"
    print(f"foxglove: ws://{host}:{served}", file=sys.stderr, flush=True)
    playing = threading.Thread(target=player.run, args=(stop, False), daemon=True)
    playing.start()
    try:
        serve(FoxgloveFeed(line), session, keys, stop)
    finally:
        line.stop()
        playing.join(timeout=5)
    return ""


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if not is_loopback_host(args.host):
        print(
            f"fleet foxglove: --host {args.host} is beyond loopback, and Foxglove's protocol has no login: serve on "
            "loopback and reach it through an SSH tunnel (docs/ros2.md)",
            file=sys.stderr,
        )
        return 2
    stop = StopFlag()
    if args.nice:
        os.nice(args.nice)
    keys = Keys(args.run)
    with open_session(BusEndpoints.from_args(args)) as session:
        scene = line_scene(session, keys, args.scene_timeout, "fleet foxglove")
        if scene is None:
            return 1
        line = FoxgloveLine(scene, ros_line_bus(session, keys, [a.name for a in scene.arms], SOURCE), args.max_rate_hz)
        try:
            port = line.start(args.host, args.port)
        except RuntimeError as exc:
            print(f"fleet foxglove: cannot listen on {args.host}:{args.port}: {exc}", file=sys.stderr)
            return 1
        print(f"foxglove: ws://{args.host}:{port}", file=sys.stderr, flush=True)
        if args.url_file:
            write_text_atomically(args.url_file, f"ws://{args.host}:{port}")
        feed = FoxgloveFeed(line)
        try:
            serve(feed, session, keys, stop)
        finally:
            line.stop()
            write_node_report(
                args.report,
                {
                    "messages_sent": line.sent,
                    "requests_refused": line.refused,
                    "dropped_messages": feed.drops.total,
                    "refused_messages": feed.drops.kinds(),
                    "stopped_by": stop.reason,
                },
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
