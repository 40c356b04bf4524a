"""`fleet record`, `fleet replay`, `fleet report`: record a running line, play a recording back, report on it."""

from __future__ import annotations

import argparse
import contextlib
import json
import math

from fleet.bus.session import BusEndpoints, add_bus_arguments
from fleet.cli.bus_flags import check_bus_flags
from fleet.cli.errors import (
    UsageError,
    err,
    out,
    output_folder,
    writable_file,
)
from fleet.monitor.options import add_monitor_arguments, exposure_warning


def cmd_report(args: argparse.Namespace) -> int:
    from fleet.record.camera_sheets import write_camera_sheets
    from fleet.record.mcap_file import Recording
    from fleet.record.report import series_from_recording, write_report

    recording = Recording(args.file)
    out_dir = output_folder("--out", args.out)
    series = series_from_recording(recording)
    written = write_report(series, out_dir) + write_camera_sheets(recording, out_dir)
    if series.summary is not None:
        (out_dir / "summary.json").write_text(json.dumps(series.summary, indent=1) + "\n")
    out.print(
        f"{args.file}: {len(series.arm_rows)} arm states, {len(series.line_rows)} line samples over "
        f"{series.end_s:.1f} sim s"
    )
    out.print(f"wrote {', '.join(p.name for p in written)} in {out_dir}")
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    import threading

    from fleet.bus.keys import Keys
    from fleet.bus.session import BusEndpoints, open_listening_session, open_session
    from fleet.common.processes import StopFlag
    from fleet.record.mcap_file import Recording
    from fleet.record.replay import Player

    recording = Recording(args.file)
    if not (math.isfinite(args.speed) and 0.01 <= args.speed <= 100):
        raise UsageError(f"--speed {args.speed:g}: give a factor from 0.01 to 100")
    run_id = args.run_id or recording.run_id
    check_bus_flags(args, run_id=run_id)
    keys = Keys(run_id)
    stop = StopFlag(watch_parent=False)
    endpoints = BusEndpoints.from_args(args)
    if endpoints.listen or endpoints.config_file:
        session_cm, endpoint = open_session(endpoints), ", ".join(endpoints.listen) or "(from the Zenoh config)"
    else:
        session, endpoint = open_listening_session(endpoints)
        session_cm = contextlib.closing(session)
    with session_cm as session, Player(recording, session, keys, args.from_s, args.speed) as player:
        clock = player.clock
        err.print(
            f"replaying {args.file}: {clock.start_s:.1f} to {clock.end_s:.1f} sim s of run {recording.run_id!r} as "
            f"run {keys.run!r} "
            f"on {endpoint} (watch it: fleet monitor --connect {endpoint} --run-id {keys.run})",
            markup=False,
            highlight=False,
        )
        if args.foxglove:
            return _replay_to_foxglove(player, session, keys, args, stop)
        if not args.monitor:
            player.run(stop, until_end=True)
            out.print(
                f"published {player.published} messages up to {clock.position_s:.1f} sim s"
                + (f" (stopped: {stop.reason})" if stop.reason else "")
            )
            return 130 if stop.reason == "SIGINT" else 0
        from fleet.monitor.app import Monitor, print_url
        from fleet.monitor.replay_panel import ReplayPanel

        warning = exposure_warning(args.host)
        if warning:
            err.print(warning, style="bold yellow", markup=False, highlight=False)
        with Monitor(session, keys, recording.scene, args.host, args.port) as monitor:
            monitor.extras.append(ReplayPanel(monitor.server, player))
            print_url(monitor, args.port)
            playing = threading.Thread(target=player.run, args=(stop, False), daemon=True)
            playing.start()
            monitor.run(stop)
            playing.join(timeout=5)
    return 130 if stop.reason == "SIGINT" else 0


def _replay_to_foxglove(player, session, keys, args: argparse.Namespace, stop) -> int:
    """The replay served to the Foxglove app, its timeline driving the playback (Ctrl-C ends)."""
    from fleet.bus.session import is_loopback_host
    from fleet.nodes.foxglove_node import serve_recording

    if not is_loopback_host(args.host):
        raise UsageError(f"--host {args.host}: Foxglove's protocol has no login; serve on loopback (an SSH tunnel)")
    player.control(playing=False)  # the app starts it
    why = serve_recording(player, session, keys, args.host, args.foxglove_port, stop)
    if why:
        raise UsageError(why)
    return 130 if stop.reason == "SIGINT" else 0


def cmd_record(args: argparse.Namespace) -> int:
    from fleet.nodes import recorder_node

    if not (args.connect or args.zenoh_config):
        raise UsageError(
            "fleet record needs --connect ENDPOINT (fleet run prints its bus endpoint) or --zenoh-config FILE"
        )
    check_bus_flags(args, wait_s=args.wait)
    writable_file("file", args.file)
    argv = ["--run", args.run_id, "--out", args.file, "--scene-timeout", str(args.wait), "--nice", "0"]
    argv += BusEndpoints.from_args(args).client_argv()
    return recorder_node.main(argv)


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """This group's sub-commands."""
    p = sub.add_parser(
        "record", help="record a running line to an MCAP file (attaches over the bus; Ctrl-C finishes the file)"
    )
    p.add_argument("file", help="the MCAP file to write")
    p.add_argument("--run-id", default="line", help="run id of the line (default line)")
    p.add_argument("--wait", type=float, default=15.0, help="seconds to wait for the line's sim to answer (default 15)")
    add_bus_arguments(p)
    p.set_defaults(func=cmd_record)

    p = sub.add_parser(
        "replay", help="play a recording back onto the bus; with --monitor, in the browser with a time slider"
    )
    p.add_argument("file", help="an MCAP file written by fleet run --record / fleet record")
    p.add_argument(
        "--monitor",
        action="store_true",
        help="serve the browser monitor with play, pause, scrub and speed (Ctrl-C ends)",
    )
    p.add_argument(
        "--foxglove",
        action="store_true",
        help="serve it to the Foxglove app, whose timeline plays, pauses, seeks and speeds it (Ctrl-C ends)",
    )
    p.add_argument(
        "--foxglove-port", type=int, default=8765, metavar="PORT", help="the Foxglove server's port (default 8765)"
    )
    p.add_argument("--speed", type=float, default=1.0, help="sim seconds per wall second (default 1)")
    p.add_argument("--from", dest="from_s", type=float, default=None, metavar="S", help="start at this sim time")
    p.add_argument("--run-id", default=None, help="publish as this run id (default: the recorded one)")
    add_monitor_arguments(p)
    add_bus_arguments(p)
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser(
        "report", help="time series (CSV) and plots (Gantt, throughput, separation, round trips) from a recording"
    )
    p.add_argument("file", help="an MCAP file written by fleet run --record / fleet record")
    p.add_argument("--out", required=True, metavar="DIR", help="folder for the CSVs and PNGs")
    p.set_defaults(func=cmd_report)
