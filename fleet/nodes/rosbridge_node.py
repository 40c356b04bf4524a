"""The rosbridge process: a rosbridge v2 WebSocket server (`fleet.ros.rosbridge_server`) attached to a running line
over the bus (`fleet rosbridge`, `fleet run --rosbridge`). It asks the sim for the scene, serves the line's topics,
services and actions to roslibpy, roslibjs or Foxglove, and sends their goals, e-stops and pauses over the bus.

    python -m fleet.nodes.rosbridge_node --run line --connect tcp/127.0.0.1:7447 --port 9090
"""

from __future__ import annotations

import argparse
import asyncio
import os
import sys
from pathlib import Path

from fleet.bus.keys import Keys
from fleet.bus.session import BusEndpoints, Inbox, is_loopback_host, open_session
from fleet.common.processes import StopFlag, write_node_report, write_text_atomically
from fleet.nodes.attached import OnDemandSubscriptions, add_ros_node_arguments, line_scene, ros_line_bus
from fleet.ros.rosbridge_server import RosbridgeServer

SOURCE = "rosbridge"
DRAIN_S = 0.005  # how often the bus's queued messages are taken onto the server's loop


async def serve(
    server: RosbridgeServer, inbox: Inbox, listened: OnDemandSubscriptions, args: argparse.Namespace, stop: StopFlag
) -> None:
    keys = Keys(args.run)

    async def drain() -> None:
        while not stop.should_stop():
            for key, payload in inbox.drain():
                server.on_bus(key, payload)
            server.flush_held()
            listened.want(server.needed(keys))
            await asyncio.sleep(DRAIN_S)

    def listening(port: int) -> None:
        print(f"rosbridge: ws://{args.host}:{port}", file=sys.stderr, flush=True)
        if args.url_file:
            write_text_atomically(args.url_file, f"ws://{args.host}:{port}")

    drainer = asyncio.create_task(drain())
    try:
        await server.serve(args.host, args.port, stop.should_stop, listening)
    finally:
        drainer.cancel()


def read_secret(path: str) -> str | None:
    """The secret in a file (surrounding whitespace ignored); None if it cannot be read or is empty."""
    try:
        return Path(path).read_text().strip() or None
    except (OSError, UnicodeDecodeError):
        return None


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fleet-rosbridge", description=__doc__.splitlines()[0])
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on (loopback; see docs/ros2.md)")
    parser.add_argument("--port", type=int, default=9090, help="WebSocket port (0: any free one)")
    parser.add_argument(
        "--secret-file",
        help="a file holding the secret clients' MACs are made with (rosauth): every client must `auth` first; "
        "needed to listen beyond loopback",
    )
    parser.add_argument("--url-file", help="write the server's ws:// URL to this file once it listens")
    add_ros_node_arguments(parser)
    return parser


def exposure_refusal(host: str, secret_file: str | None) -> str | None:
    """Why the server may not listen on `host` with `secret_file` (a secret is needed beyond loopback), or None."""
    if secret_file and not read_secret(secret_file):
        return f"--secret-file {secret_file}: not a readable file with a secret"
    if not is_loopback_host(host) and not secret_file:
        return f"--host {host} is beyond loopback: give --secret-file (clients then authenticate)"
    return None


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    refusal = exposure_refusal(args.host, args.secret_file)
    if refusal:
        print(f"fleet rosbridge: {refusal}", file=sys.stderr)
        return 2
    secret = read_secret(args.secret_file) if args.secret_file else None
    stop = StopFlag()
    if args.nice:
        os.nice(args.nice)
    keys = Keys(args.run)
    with open_session(BusEndpoints.from_args(args)) as session:
        scene = line_scene(session, keys, args.scene_timeout, "fleet rosbridge")
        if scene is None:
            return 1
        server = RosbridgeServer(
            scene, ros_line_bus(session, keys, [a.name for a in scene.arms], SOURCE), secret, args.max_rate_hz
        )
        inbox = Inbox()
        results = session.declare_subscriber(keys.all_arms("result"), inbox)  # few: one per goal
        listened = OnDemandSubscriptions(session, inbox)
        try:
            asyncio.run(serve(server, inbox, listened, args, stop))
        except OSError as exc:
            print(f"fleet rosbridge: cannot listen on {args.host}:{args.port}: {exc.strerror or exc}", file=sys.stderr)
            return 1
        finally:
            results.undeclare()
            listened.close()
            write_node_report(
                args.report,
                {
                    "goals_sent": server.actions.sent,
                    "requests_refused": server.requests_refused,
                    "requests_failed": server.requests_failed,
                    "dropped_messages": server.drops.total,
                    "refused_messages": server.drops.kinds(),
                    "clients_dropped_messages": sum(c.dropped for c in server.clients),
                    "stopped_by": stop.reason,
                },
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
