"""`fleet rosbridge`, `fleet foxglove` and `fleet ros2`: serve a running line to robotics tools (rosbridge's
WebSocket, Foxglove's, rmw_zenoh)."""

from __future__ import annotations

import argparse
import math

from fleet.bus.session import BusEndpoints, add_bus_arguments
from fleet.cli.bus_flags import check_bus_flags
from fleet.cli.errors import UsageError
from fleet.nodes.attached import add_rate_argument


def checked_rate(hz: float, flag: str = "--max-rate-hz") -> float:
    """A cap on the ROS topics' rate: 0 (no cap) or a positive rate."""
    if not (math.isfinite(hz) and hz >= 0):
        raise UsageError(f"{flag} {hz:g}: give a rate in wall Hz (0: no cap)")
    return hz


def _attached_argv(args: argparse.Namespace) -> list[str]:
    """What every front end attached to a running line is given: the run, how long to wait for its sim, the
    topics' rate cap and the bus (checked first)."""
    check_bus_flags(args, wait_s=args.wait)
    rate = checked_rate(args.max_rate_hz)
    argv = ["--run", args.run_id, "--scene-timeout", str(args.wait), "--max-rate-hz", str(rate)]
    return [*argv, *BusEndpoints.from_args(args).client_argv()]


def cmd_rosbridge(args: argparse.Namespace) -> int:
    from fleet.nodes import rosbridge_node

    if not (args.connect or args.zenoh_config):
        raise SystemExit(
            "fleet: error: fleet rosbridge needs --connect ENDPOINT or --zenoh-config FILE (fleet run prints both; "
            "on a run's secure bus use its bus/ros.json5)"
        )
    if not 0 <= args.port <= 65535:
        raise SystemExit(f"fleet: error: --port {args.port}: a TCP port is 0 to 65535 (0: any free port)")
    if refusal := rosbridge_node.exposure_refusal(args.host, args.secret_file):
        raise UsageError(refusal)
    argv = [*_attached_argv(args), "--host", args.host, "--port", str(args.port)]
    if args.secret_file:
        argv += ["--secret-file", args.secret_file]
    return rosbridge_node.main(argv)


def cmd_foxglove(args: argparse.Namespace) -> int:
    from fleet.nodes import foxglove_node

    if not (args.connect or args.zenoh_config):
        raise UsageError(
            "fleet foxglove needs --connect ENDPOINT or --zenoh-config FILE (fleet run prints both; on a run's secure "
            "bus use its bus/ros.json5)"
        )
    if not 0 <= args.port <= 65535:
        raise UsageError(f"--port {args.port}: a TCP port is 0 to 65535 (0: any free port)")
    return foxglove_node.main([*_attached_argv(args), "--host", args.host, "--port", str(args.port)])


def cmd_ros2(args: argparse.Namespace) -> int:
    from fleet.nodes import ros2_node

    if not (args.connect or args.zenoh_config):
        raise SystemExit(
            "fleet: error: fleet ros2 serve needs --connect ENDPOINT or --zenoh-config FILE (on a run's secure bus, "
            "its bus/ros.json5; that run must have been started with --ros2 for its router to let the topics through)"
        )
    return ros2_node.main([*_attached_argv(args), "--domain-id", str(args.domain_id)])


def cmd_ros2_controllers(args: argparse.Namespace) -> int:
    from fleet.cli.errors import writable_file
    from fleet.common.scene_loading import load_checked_scene
    from fleet.ros.moveit import moveit_controllers_yaml

    text = moveit_controllers_yaml(load_checked_scene(args.scene, arms=args.arms))
    if args.out:
        writable_file("--out", args.out)
        with open(args.out, "w") as f:
            f.write(text)
    else:
        print(text, end="")
    return 0


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """This group's sub-commands."""
    p = sub.add_parser(
        "rosbridge",
        help="serve a running line to roslibpy, roslibjs and Foxglove (rosbridge v2, attaches over the bus)",
    )
    p.add_argument("--run-id", default="line", help="run id of the line (default line)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default loopback)")
    p.add_argument("--port", type=int, default=9090, help="WebSocket port (default 9090)")
    p.add_argument(
        "--secret-file",
        metavar="FILE",
        help="clients authenticate with MACs made from this secret (rosauth's `auth`); needed beyond loopback",
    )
    p.add_argument("--wait", type=float, default=15.0, help="seconds to wait for the line's sim to answer (default 15)")
    add_rate_argument(p)
    add_bus_arguments(p)
    p.set_defaults(func=cmd_rosbridge)
    p = sub.add_parser(
        "foxglove", help="serve a running line to the Foxglove app (its own WebSocket protocol, attaches over the bus)"
    )
    p.add_argument("--run-id", default="line", help="run id of the line (default line)")
    p.add_argument("--host", default="127.0.0.1", help="loopback address to listen on (default 127.0.0.1)")
    p.add_argument("--port", type=int, default=8765, help="WebSocket port (default 8765, the app's)")
    p.add_argument("--wait", type=float, default=15.0, help="seconds to wait for the line's sim to answer (default 15)")
    add_rate_argument(p)
    add_bus_arguments(p)
    p.set_defaults(func=cmd_foxglove)
    ros2 = sub.add_parser("ros2", help="ROS 2: native topics on a line's router, MoveIt's controllers file")
    group = ros2.add_subparsers(dest="ros2_command", required=True)
    c = group.add_parser(
        "controllers", help="write moveit_controllers.yaml for a scene (FollowJointTrajectory per arm)"
    )
    c.add_argument("scene", help="bundled scene name or scene file")
    c.add_argument("--arms", type=int, default=None, help="arm count for scenes with an arm row")
    c.add_argument("--out", metavar="FILE", help="write it here (default: standard output)")
    c.set_defaults(func=cmd_ros2_controllers)
    p = group.add_parser("serve", help="publish a running line's ROS 2 topics natively on its router (rmw_zenoh)")
    p.add_argument("--run-id", default="line", help="run id of the line (default line)")
    p.add_argument(
        "--ros-domain-id", "--domain-id", dest="domain_id", type=int, default=0, help="ROS_DOMAIN_ID (default 0)"
    )
    p.add_argument("--wait", type=float, default=15.0, help="seconds to wait for the line's sim to answer (default 15)")
    add_rate_argument(p)
    add_bus_arguments(p)
    p.set_defaults(func=cmd_ros2)
