"""The recorder process: taps a run's bus and writes everything it hears to an MCAP file (`fleet record`,
`fleet run --record`), off the sim's hot path.

It subscribes first, asks the sim for its scene, then says it listens (`Keys.recorder_ready`) until it hears
the line, so a sim told to await it (lockstep under `fleet run --record`) loses nothing. On SIGTERM or SIGINT
it records what is still queued, adds the run's summary if `--summary-file` exists by then, and finishes the file.

    python -m fleet.nodes.recorder_node --run line --connect tcp/127.0.0.1:7447 --out run.mcap
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from fleet.bus.keys import Keys
from fleet.bus.scene_query import SceneUnavailable, fetch_scene
from fleet.bus.session import BusEndpoints, Inbox, add_bus_arguments, open_session
from fleet.processes import StopFlag, write_report
from fleet.record.mcap_file import RecordingWriter
from fleet.record.recorder import Recorder, recorded_keys

READY_EVERY_S = 0.1
DRAIN_GRACE_S = 0.3  # after a stop: messages still on their way are recorded too
RECORDER_NICENESS = 5


def read_summary(path: str | None) -> dict | None:
    if not path or not Path(path).is_file():
        return None
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None


def record(session, keys: Keys, out: str, stop: StopFlag, scene_timeout_s: float, summary_file: str | None) -> dict:
    """Record until `stop`; the figures of the recording."""
    inbox = Inbox()
    subs = [session.declare_subscriber(k, inbox) for k in recorded_keys(keys)]
    try:
        scene = fetch_scene(session, keys, scene_timeout_s)
        ready = session.declare_publisher(keys.recorder_ready)
        started = time.monotonic()
        with RecordingWriter(out, scene.model_dump_json(), keys.run) as writer:
            recorder = Recorder(writer, scene, keys)
            heard_line, ready_at = False, 0.0
            while not stop.should_stop():
                if not heard_line and time.monotonic() >= ready_at:
                    ready.put(b"")
                    ready_at = time.monotonic() + READY_EVERY_S
                inbox.wait(READY_EVERY_S)
                for key, payload in inbox.drain():
                    recorder.take(key, payload)
                    heard_line = True
            time.sleep(DRAIN_GRACE_S)
            for key, payload in inbox.drain():
                recorder.take(key, payload)
            recorder.finish(read_summary(summary_file))
        ready.undeclare()
    finally:
        for sub in subs:
            sub.undeclare()
    return {
        "file": out, "messages_written": writer.messages, "bus_messages": sum(recorder.stats.by_key.values()),
        "undecodable": recorder.stats.undecodable, "dropped_messages": recorder.drops.total,
        "bytes": Path(out).stat().st_size, "sim_seconds": recorder.now_s, "wall_seconds": round(time.monotonic() - started, 3),
        "stopped_by": stop.reason,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fleet-recorder", description=__doc__.splitlines()[0])
    parser.add_argument("--run", default="line", help="run id of the line to record")
    parser.add_argument("--out", required=True, help="the MCAP file to write")
    parser.add_argument("--scene-timeout", type=float, default=15.0, help="seconds to wait for the sim to say its scene")
    parser.add_argument("--summary-file", help="at the end, add the run summary found in this JSON file")
    parser.add_argument("--nice", type=int, default=RECORDER_NICENESS, help="scheduling niceness: the recorder yields the CPU to the line")
    parser.add_argument("--report", help="write the recording's figures to this JSON file at exit")
    add_bus_arguments(parser)
    args = parser.parse_args(argv)
    stop = StopFlag()
    if args.nice:
        os.nice(args.nice)
    with open_session(BusEndpoints.from_args(args)) as session:
        try:
            report = record(session, Keys(args.run), args.out, stop, args.scene_timeout, args.summary_file)
        except SceneUnavailable as exc:
            print(f"fleet record: {exc}", file=sys.stderr)
            return 1
    write_report(args.report, report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
