"""The recorder process: writes every message of a run to an MCAP file (`fleet record`, `fleet run --record`),
off the sim's hot path.

It hears the run one of two ways, and records both alike (`record`):
- from the sim's spool (`--spool FILE`, what `fleet run --record` does): the sim appends every message its
  session hears to a file; the run id and scene are in the file, and the recorder needs no bus session;
- on the bus (`--connect ...`, `fleet record`): it subscribes first, asks the sim for its scene, then says it
  listens (`Keys.recorder_ready`) until it hears the line, so a sim told to await it loses nothing.
What writes the file (mcap, rosbags, Pinocchio, the arms' models) is loaded once the line is heard, so the
line's start-up never waits on it. On SIGTERM or SIGINT it records what is still queued, adds the run's
summary if `--summary-file` exists by then, and finishes the file.

    python -m fleet.nodes.recorder_node --run line --connect tcp/127.0.0.1:7447 --out run.mcap
    python -m fleet.nodes.recorder_node --spool /tmp/clawfleet-run-xyz/bus.spool --out run.mcap
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

from fleet.bus.keys import Keys
from fleet.bus.scene_query import SceneUnavailable, fetch_scene, run_scene
from fleet.bus.session import BusEndpoints, Tap, add_bus_arguments, open_session
from fleet.common.processes import StopFlag, run_on_idle_cpu, write_node_report
from fleet.record.spool import SpoolError, SpoolReader
from scenes.schema import Scene

READY_EVERY_S = 0.1
DRAIN_EVERY_S = 0.1
QUIET_MESSAGES = 20  # a drain with fewer is a trickle (heartbeats, progress): the line is paused or over
# a drain with more: the line runs (a lockstep line at full speed sends hundreds; its start-up a few dozen)
RUNNING_MESSAGES = 100
CATCH_UP_SLICE = 500  # held-back messages written per round while the line is quiet
HOLD_AT_MOST = 200_000  # heard messages held back at most (some 60 MB); beyond, they are written as they come
DRAIN_GRACE_S = 0.1  # after a stop: messages still on their way are recorded too (until a drain finds none)
DRAIN_GRACE_EVERY_S = 0.02
RECORDER_NICENESS = 5
TAIL_WORKERS = 2  # processes that write the held messages once the line is over (reading a spool: no session to fork)
SUMMARY_POLL_S = 0.01


def yield_cpu(niceness: int) -> None:
    """Run only on CPU time the line leaves idle (SCHED_IDLE, Linux), else at a lower priority: lockstep
    processes wait on each other often, and the recorder catches up in those gaps."""
    if not run_on_idle_cpu():
        os.nice(niceness)


class LazyRecording:
    """The file and the `Recorder` that fills it, made at first use (`recorder`): importing mcap, rosbags and
    Pinocchio and loading the arms' models waits until the line is heard."""

    def __init__(self, out: str, scene: Scene, keys: Keys) -> None:
        self.out, self.scene, self.keys = out, scene, keys
        self._writer = None
        self._recorder = None

    @property
    def recorder(self):
        if self._recorder is None:
            from fleet.record.mcap_file import RecordingWriter
            from fleet.record.recorder import Recorder

            self._writer = RecordingWriter(self.out, self.scene.model_dump_json(), self.keys.run)
            self._recorder = Recorder(self._writer, self.scene, self.keys)
        return self._recorder

    def close(self) -> None:
        """Finish the file (its index) even on an error, so what was written can be read."""
        if self._writer is not None:
            self._writer.close()


def read_summary(path: str | None) -> dict | None:
    if not path or not Path(path).is_file():
        return None
    try:
        return json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None


def take(recording: LazyRecording, backlog: deque, count: int) -> None:
    if count <= 0 or not backlog:
        return
    recorder = recording.recorder
    for _ in range(min(count, len(backlog))):
        recorder.take(*backlog.popleft())


def catch_up(recording: LazyRecording, backlog: deque) -> bool:
    """One slice of the held-back messages written (raw and ROS topics); whether there was any."""
    had = bool(backlog)
    take(recording, backlog, CATCH_UP_SLICE)
    return had


class Source(Protocol):
    """Where the recorder hears the run: a tap on the bus (`Tap`), or the sim's spool file (`SpoolReader`).
    `ended`: nothing more will come (the spool's end mark, written as the sim's loop ends; a tap never ends)."""

    ended: bool

    def drain(self) -> list[tuple[str, bytes]]: ...


def drain_to_the_end(source: Source) -> list[tuple[str, bytes]]:
    """After a stop: what is still on its way, until a drain finds nothing new (at most `DRAIN_GRACE_S`)."""
    heard = source.drain()
    if source.ended:
        return heard
    until = time.monotonic() + DRAIN_GRACE_S
    while time.monotonic() < until:
        time.sleep(DRAIN_GRACE_EVERY_S)
        batch = source.drain()
        heard.extend(batch)
        if not batch:
            break
    return heard


def record(
    source: Source,
    scene: Scene,
    keys: Keys,
    out: str,
    stop: StopFlag,
    summary_file: str | None,
    hold: bool = False,
    say_ready: Callable[[], None] | None = None,
    tail_workers: int = 1,
) -> dict:
    """Record until `stop`; the figures of the recording. `hold`: keep what is heard in memory while the line is
    busy and write it when it is quiet or over (a lockstep line at full speed leaves no CPU to spare). `say_ready`:
    said every `READY_EVERY_S` until the line is heard (a sim told to await a recorder starts then). `tail_workers`:
    processes that write what is held once the line is over (more than one forks: only where no bus session is open)."""
    started = time.monotonic()
    recording = LazyRecording(out, scene, keys)
    try:
        backlog: deque[tuple[str, bytes]] = deque()  # heard, in publish order, not written yet
        heard_line, ran, ready_at = False, False, 0.0
        while not stop.should_stop():
            if not heard_line and time.monotonic() >= ready_at:
                if say_ready is not None:
                    say_ready()
                ready_at = time.monotonic() + READY_EVERY_S
                _ = recording.recorder  # loaded while the line starts, on idle CPU time
            batch = source.drain()
            backlog.extend(batch)
            heard_line = heard_line or bool(batch)
            ran = ran or len(batch) >= RUNNING_MESSAGES
            quiet = ran and len(batch) < QUIET_MESSAGES  # not before the line ran: its start-up comes first
            run_on_idle_cpu(not quiet)  # quiet: the run now waits on the file
            if not hold or len(backlog) > HOLD_AT_MOST:  # as it comes (a realtime line leaves time), or a long run
                take(recording, backlog, len(backlog) if not hold else len(backlog) - HOLD_AT_MOST // 2)
            if source.ended:
                break  # the sim's loop is over: write the rest now, while the launcher stops the line
            if quiet and catch_up(recording, backlog):
                continue  # the line is quiet (paused, or over; heartbeats go on): write what was held back meanwhile
            time.sleep(DRAIN_EVERY_S if heard_line else READY_EVERY_S)  # a batch at a time
        run_on_idle_cpu(False)
        backlog.extend(drain_to_the_end(source))
        recorder = recording.recorder
        recorder.take_all(list(backlog), workers=tail_workers)  # the line is over: both cores are free
        backlog.clear()
        while not stop.should_stop():  # the launcher says stop once the summary is written
            time.sleep(SUMMARY_POLL_S)
        recorder.finish(read_summary(summary_file))
    finally:
        recording.close()
    return {
        "file": out,
        "messages_written": recorder.writer.messages,
        "bus_messages": sum(recorder.stats.by_key.values()),
        "undecodable": recorder.stats.undecodable,
        "dropped_messages": recorder.drops.total,
        "bytes": Path(out).stat().st_size,
        "sim_seconds": recorder.now_s,
        "wall_seconds": round(time.monotonic() - started, 3),
        "stopped_by": stop.reason,
    }


def record_bus(
    session, keys: Keys, out: str, stop: StopFlag, scene_timeout_s: float, summary_file: str | None, hold: bool = False
) -> dict:
    """Record what a tap on the bus hears (`fleet record`): the scene asked from the sim, then "ready" said until
    the line is heard."""
    with Tap(session, keys.recorded()) as tap:
        scene = fetch_scene(session, keys, scene_timeout_s)
        ready = session.declare_publisher(keys.recorder_ready)
        try:
            return record(tap, scene, keys, out, stop, summary_file, hold, say_ready=lambda: ready.put(b""))
        finally:
            ready.undeclare()


def record_spool(
    path: str, out: str, stop: StopFlag, timeout_s: float, summary_file: str | None, hold: bool = False
) -> dict:
    """Record from the sim's spool (`fleet run --record`): the scene is in its header; no bus session at all."""
    reader = SpoolReader(path)
    try:
        header = reader.wait_for_header(timeout_s, give_up=stop.should_stop)
        if header is None:
            raise SceneUnavailable(f"the sim wrote no spool to {path} within {timeout_s:g} s")
        scene = run_scene(header.scene_json, header.run_id)
        return record(reader, scene, Keys(header.run_id), out, stop, summary_file, hold, tail_workers=TAIL_WORKERS)
    finally:
        reader.close()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fleet-recorder", description=__doc__.splitlines()[0])
    parser.add_argument("--run", default="line", help="run id of the line to record")
    parser.add_argument("--out", required=True, help="the MCAP file to write")
    parser.add_argument(
        "--scene-timeout", type=float, default=15.0, help="seconds to wait for the sim to say its scene"
    )
    parser.add_argument("--summary-file", help="at the end, add the run summary found in this JSON file")
    parser.add_argument(
        "--nice",
        type=int,
        default=RECORDER_NICENESS,
        help=(
            "0: a normal process; else it runs on idle CPU time (SCHED_IDLE), or at this niceness where that is refused"
        ),
    )
    parser.add_argument(
        "--hold",
        action="store_true",
        help="write while the line is quiet or over, not as it runs (lockstep at full speed)",
    )
    parser.add_argument(
        "--spool",
        help="record the sim's spool file (its `--spool`) instead of tapping the bus; the run id and scene are in it",
    )
    parser.add_argument(
        "--once",
        action="store_true",
        help="with --spool: write a finished run's spool from start to end and exit (how `fleet run` replaces a "
        "recorder that died)",
    )
    parser.add_argument("--report", help="write the recording's figures to this JSON file at exit")
    add_bus_arguments(parser)
    args = parser.parse_args(argv)
    if args.once and not args.spool:
        parser.error("--once records a spool: give --spool FILE")
    stop = StopFlag()
    if args.once:
        stop.reason = "once: the spool is complete"
    if args.nice:
        yield_cpu(args.nice)
    endpoints = BusEndpoints.from_args(args)
    try:
        if args.spool:
            report = record_spool(args.spool, args.out, stop, args.scene_timeout, args.summary_file, args.hold)
        else:
            with open_session(endpoints) as session:
                report = record_bus(
                    session, Keys(args.run), args.out, stop, args.scene_timeout, args.summary_file, args.hold
                )
    except (SceneUnavailable, SpoolError) as exc:
        print(f"fleet record: {exc}", file=sys.stderr)
        return 1
    write_node_report(args.report, report)
    return 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    # the file, the report and the session are closed: skip tearing down the modules (a run waits on this exit)
    os._exit(code)
