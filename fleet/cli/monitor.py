"""`fleet monitor`: watch and control a running line in the browser."""

from __future__ import annotations

import argparse

from fleet.bus.session import BusEndpoints, add_bus_arguments
from fleet.cli.bus_flags import check_bus_flags
from fleet.monitor.options import add_monitor_arguments


def cmd_monitor(args: argparse.Namespace) -> int:
    from fleet.nodes import monitor_node

    if not (args.connect or args.zenoh_config):
        raise SystemExit(
            "fleet: error: fleet monitor needs --connect ENDPOINT (fleet run prints its bus endpoint; or start it "
            "with --listen) "
            "or --zenoh-config FILE"
        )
    check_bus_flags(args, wait_s=args.wait)
    argv = ["--run", args.run_id, "--host", args.host, "--port", str(args.port), "--scene-timeout", str(args.wait)]
    argv += BusEndpoints.from_args(args).client_argv()
    return monitor_node.main(argv)


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """This group's sub-commands."""
    p = sub.add_parser("monitor", help="watch and control a running line in the browser (attaches over the bus)")
    p.add_argument("--run-id", default="line", help="run id of the line (default line)")
    p.add_argument("--wait", type=float, default=15.0, help="seconds to wait for the line's sim to answer (default 15)")
    add_monitor_arguments(p)
    add_bus_arguments(p)
    p.set_defaults(func=cmd_monitor)
