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
from collections import deque
from pathlib import Path

from fleet.bus.keys import Keys
from fleet.bus.scene_query import SceneUnavailable, fetch_scene
from fleet.bus.session import BusEndpoints, Tap, add_bus_arguments, open_session
from fleet.processes import StopFlag, read_when_written, write_report
from fleet.record.mcap_file import RecordingWriter
from fleet.record.recorder import Recorder, recorded_keys

READY_EVERY_S = 0.1
DRAIN_EVERY_S = 0.1
QUIET_S = 0.1  # nothing heard for this long: the line is paused or over
CATCH_UP_SLICE = 500  # held-back messages written per round while nothing new arrives
HOLD_AT_MOST = 200_000  # heard messages held back at most (some 60 MB); beyond, they are written as they come
DRAIN_GRACE_S = 0.1  # after a stop: messages still on their way are recorded too
RECORDER_NICENESS = 5


def yield_cpu(niceness: int) -> None:
    """Run only on CPU time the line leaves idle (SCHED_IDLE, Linux), else at a lower priority: lockstep
    processes wait on each other often, and the recorder catches up in those gaps."""
    try:
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
    except (AttributeError, OSError):
        os.nice(niceness)


def read_summary(path: str | None) -> dict | None:
    if not path or not Path(path).is_file():
        return None
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None


def take(recorder: Recorder, backlog: deque, count: int) -> None:
    for _ in range(min(count, len(backlog))):
        recorder.take(*backlog.popleft())


def catch_up(recorder: Recorder, backlog: deque) -> bool:
    """One slice of the held-back messages written (raw and ROS topics); whether there was any."""
    had = bool(backlog)
    take(recorder, backlog, CATCH_UP_SLICE)
    return had


def record(session, keys: Keys, out: str, stop: StopFlag, scene_timeout_s: float, summary_file: str | None, hold: bool = False) -> dict:
    """Record until `stop`; the figures of the recording. `hold`: keep what is heard in memory while the line is
    busy and write it when it is quiet or over (a lockstep line at full speed leaves no CPU to spare)."""
    tap = Tap(session, recorded_keys(keys))
    try:
        scene = fetch_scene(session, keys, scene_timeout_s)
        ready = session.declare_publisher(keys.recorder_ready)
        started = time.monotonic()
        with RecordingWriter(out, scene.model_dump_json(), keys.run) as writer:
            recorder = Recorder(writer, scene, keys)
            backlog: deque[tuple[str, bytes]] = deque()  # heard, in publish order, not written yet
            heard_line, ready_at, last_heard = False, 0.0, 0.0
            while not stop.should_stop():
                if not heard_line and time.monotonic() >= ready_at:
                    ready.put(b"")
                    ready_at = time.monotonic() + READY_EVERY_S
                batch = tap.drain()
                backlog.extend(batch)
                if batch:
                    heard_line, last_heard = True, time.monotonic()
                if not hold or len(backlog) > HOLD_AT_MOST:  # as it comes (a realtime line leaves time), or a long run
                    take(recorder, backlog, len(backlog) if not hold else len(backlog) - HOLD_AT_MOST // 2)
                if heard_line and not batch and time.monotonic() - last_heard > QUIET_S and catch_up(recorder, backlog):
                    continue  # the line is quiet (paused, or over): write what was held back meanwhile
                time.sleep(DRAIN_EVERY_S if heard_line else READY_EVERY_S)  # a batch at a time
            time.sleep(DRAIN_GRACE_S)
            backlog.extend(tap.drain())
            take(recorder, backlog, len(backlog))
            recorder.finish(read_summary(summary_file))
        ready.undeclare()
    finally:
        tap.close()
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
    parser.add_argument("--nice", type=int, default=RECORDER_NICENESS, help="0: a normal process; else it runs on idle CPU time (SCHED_IDLE), or at this niceness where that is refused")
    parser.add_argument("--hold", action="store_true", help="write while the line is quiet or over, not as it runs (lockstep at full speed)")
    parser.add_argument("--endpoint-file", help="connect to the endpoint written to this file (wait for it; the launcher's sim writes it)")
    parser.add_argument("--report", help="write the recording's figures to this JSON file at exit")
    add_bus_arguments(parser)
    args = parser.parse_args(argv)
    stop = StopFlag()
    if args.nice:
        yield_cpu(args.nice)
    endpoints = BusEndpoints.from_args(args)
    if args.endpoint_file:  # started beside the sim: its imports overlap the sim's start-up
        endpoint = read_when_written(args.endpoint_file, args.scene_timeout, give_up=stop.should_stop)
        if endpoint is None:
            print(f"fleet record: no endpoint in {args.endpoint_file} within {args.scene_timeout:.0f} s", file=sys.stderr)
            return 1
        endpoints = BusEndpoints(endpoints.listen, (*endpoints.connect, endpoint), endpoints.config_file)
    with open_session(endpoints) as session:
        try:
            report = record(session, Keys(args.run), args.out, stop, args.scene_timeout, args.summary_file, args.hold)
        except SceneUnavailable as exc:
            print(f"fleet record: {exc}", file=sys.stderr)
            return 1
    write_report(args.report, report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
