"""The monitor process: a Viser page of a running line, attached over the bus (`fleet monitor`, `fleet run --monitor`).

It asks the sim for the scene it runs, then draws what the bus carries and sends
the page's controls back over it like any other client.

    python -m fleet.nodes.monitor_node --run line --connect tcp/127.0.0.1:7447 --port 8080
"""

from __future__ import annotations

import argparse
import os
import sys

from fleet.bus.keys import Keys
from fleet.bus.session import BusEndpoints, add_bus_arguments, open_session
from fleet.common.processes import StopFlag, write_node_report, write_text_atomically
from fleet.monitor.app import Monitor, print_url
from fleet.monitor.options import DEFAULT_RATE_HZ, add_monitor_arguments, exposure_warning
from fleet.nodes.attached import line_scene

MONITOR_NICENESS = 10


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fleet-monitor", description=__doc__.splitlines()[0])
    parser.add_argument("--run", default="line", help="run id of the line to watch")
    add_monitor_arguments(parser)
    parser.add_argument("--rate", type=float, default=DEFAULT_RATE_HZ, help="page updates per second")
    parser.add_argument(
        "--scene-timeout", type=float, default=15.0, help="seconds to wait for the sim to say its scene"
    )
    parser.add_argument(
        "--nice",
        type=int,
        default=MONITOR_NICENESS,
        help="scheduling niceness: a viewer yields the CPU to the line it watches",
    )
    parser.add_argument("--url-file", help="write the page's URL to this file once it serves")
    parser.add_argument("--report", help="write the monitor's figures to this JSON file at exit")
    add_bus_arguments(parser)
    args = parser.parse_args(argv)
    stop = StopFlag()
    if args.nice:
        os.nice(args.nice)
    warning = exposure_warning(args.host)
    if warning:
        print(warning, file=sys.stderr)
    keys = Keys(args.run)
    with open_session(BusEndpoints.from_args(args)) as session:
        scene = line_scene(session, keys, args.scene_timeout, "fleet monitor")
        if scene is None:
            return 1
        with Monitor(session, keys, scene, args.host, args.port) as monitor:
            print_url(monitor, args.port)
            if args.url_file:
                write_text_atomically(args.url_file, monitor.url)
            try:
                monitor.run(stop, args.rate)
            finally:
                write_node_report(
                    args.report,
                    {
                        "url": monitor.url,
                        "frames": monitor.frames,
                        "frames_per_s": round(monitor.frames_per_s, 2),
                        "messages_taken": monitor.feed.taken,
                        "most_pages_open": monitor.most_pages_open,
                        "dropped_messages": monitor.feed.drops.total,
                        "refused_messages": monitor.feed.drops.kinds(),
                        "controls_sent": monitor.controls.sent,
                        "stopped_by": stop.reason,
                    },
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
