"""The sim server: owns the physics world and every arm's trajectory tracker; states to each controller at its rate.

Each arm's tracker (`robots.tracker`, through `fleet.sim.tracking`) follows the
trajectory goals on the arm's `goal` key at the servo rate (the scene's `control_hz`)
and publishes one result per goal; the physics runs `physics_hz / control_hz` steps a
tick. Each controller gets its arm's state at the ticks it asks for (`ControllerStep.
next_tick`, 20 Hz by default) and answers it within one of its periods: the physics
runs on while controllers think. In `lockstep` an answer (and the goals it names) is
applied at the arm's next due tick, and the server waits there only if it is not in
yet; the coordinator's `CoordTick` for a frame is awaited likewise at the next tick
that publishes states. So a run repeats exactly, and every process works in parallel
with the physics. A controller silent past the lockstep timeout is marked lost and its
arm held (its goals aborted); one that answers again rejoins. In `realtime` answers
and goals are applied when they arrive, and an arm whose controller misses its
deadline (`watchdog_s` after the tick its answer was due) is held by the tracker's
watchdog. The e-stop aborts every goal and holds every arm. Goals from anyone else
(a user's trajectory client) are applied at the arm's next due tick in lockstep, on
arrival in realtime or without controllers. Network faults (the scene's `network`, or
`--latency-ms/--jitter-ms/--loss`) put each state, frame and answer in flight on its link
(`fleet.bus.flights`): in lockstep for whole ticks of sim time, in realtime on the wall clock.

    python -m fleet.nodes.sim_server --scene assembly_line --run demo --listen tcp/127.0.0.1:7447 --duration 60
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import sys
import threading
import time
from pathlib import Path

import numpy as np
import zenoh

from fleet.bus.faults import add_fault_arguments, network_from_args
from fleet.bus.images import RGB_ENCODINGS
from fleet.bus.keys import Keys
from fleet.bus.router_audit import RouterAudit
from fleet.bus.session import BusEndpoints, add_bus_arguments, make_config, open_listening_session
from fleet.common.processes import (
    StopFlag,
    add_scene_arguments,
    node_arguments,
    write_node_report,
    write_text_atomically,
)
from fleet.common.realtime_priority import request_realtime_priority
from fleet.record.spool import BusSpool
from fleet.sim.server import COORDINATOR_TIMEOUT_S, LOCKSTEP_TIMEOUT_S, SimServer
from fleet.sim.sim_snapshot import RunFacts, SimSnapshots, forget_wall_clock_flights, restore_sim
from fleet.sim.snapshot_asks import await_restored
from fleet.sim.world import World
from fleet.snapshot.process_state import StateError
from fleet.snapshot.snapshot_file import RunSnapshot, SceneSource, SnapshotError, read_snapshot, state_of


def save_target_log(path: str, log: list) -> None:
    """Drive targets per tick and arm (positions, velocities, gripper), as one array each in an .npz file."""
    arrays = {}
    for i, part in enumerate(("position", "velocity", "gripper")):
        arrays[part] = np.asarray([[arm[i] for arm in tick] for tick in log], dtype=float)
    np.savez(path, **arrays)


def await_ready(session: zenoh.Session, key: str, timeout_s: float) -> bool:
    """Wait until a node says on `key` that it listens (a recorder, perception: their subscribers are declared before
    they say so)."""
    heard = threading.Event()
    sub = session.declare_subscriber(key, lambda _sample: heard.set())
    try:
        return heard.wait(timeout_s)
    finally:
        sub.undeclare()


def add_await_arguments(parser: argparse.ArgumentParser) -> None:
    """What the sim waits for before its clock starts: nodes that must not miss the line's first tick."""
    parser.add_argument(
        "--await-recorder",
        type=float,
        metavar="S",
        default=0.0,
        help="start the clock only once a recorder listens (wait at most S wall seconds)",
    )
    parser.add_argument(
        "--await-perception",
        type=float,
        metavar="S",
        default=0.0,
        help="start the clock only once a perception process listens (wait at most S wall seconds)",
    )
    parser.add_argument(
        "--await-eyes",
        type=float,
        metavar="S",
        default=0.0,
        help="start the clock only once the coordinator's allocator that sees listens to the cameras (at most S s)",
    )


def add_output_arguments(parser: argparse.ArgumentParser) -> None:
    """What the sim writes besides the line: its report, the drive targets, the bus spool, the router's audit."""
    parser.add_argument("--report", help="write the end-of-run figures to this JSON file")
    parser.add_argument(
        "--record-targets",
        metavar="FILE",
        help="save every tick's drive targets (.npz): `fleet bench run` replays them",
    )
    parser.add_argument(
        "--spool",
        metavar="FILE",
        help=(
            "append every message of the run's bus, as this router hears it, to FILE (`fleet run --record` turns it "
            "into MCAP)"
        ),
    )
    parser.add_argument(
        "--cameras",
        metavar="NAMES",
        help="render the scene's cameras (all, or names joined by commas) and put their images on the bus",
    )
    parser.add_argument("--camera-encoding", choices=RGB_ENCODINGS, default="png", help="how RGB images travel")
    parser.add_argument(
        "--router-audit",
        metavar="FILE",
        help="log what the router's access control refuses to FILE; the report counts it (`bus_refused`)",
    )


def build_parser() -> argparse.ArgumentParser:
    """The sim server's command line."""
    parser = argparse.ArgumentParser(prog="fleet-sim-server", description=__doc__.splitlines()[0])
    add_scene_arguments(parser)
    parser.add_argument("--duration", type=float, default=120.0, help="sim seconds")
    parser.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep")
    parser.add_argument("--speed", type=float, default=1.0)
    parser.add_argument(
        "--pause-at",
        metavar="S,S,...",
        default="",
        help="pause the line once its tick at these sim seconds has run, until resumed",
    )
    parser.add_argument(
        "--rt", action="store_true", help="realtime: the sim's loop asks for real-time scheduling (SCHED_FIFO)"
    )
    parser.add_argument(
        "--coordinator",
        action="store_true",
        help="wait for the coordinator's tick (lockstep: every 10 Hz; realtime: at start)",
    )
    parser.add_argument(
        "--lockstep-timeout",
        type=float,
        default=LOCKSTEP_TIMEOUT_S,
        help=f"wall seconds before a silent controller is lost (default {LOCKSTEP_TIMEOUT_S:g})",
    )
    parser.add_argument(
        "--coordinator-timeout",
        type=float,
        help="wall seconds a lockstep frame waits for the coordinator "
        f"(default: {COORDINATOR_TIMEOUT_S:g} s or the lockstep timeout if longer; longer when a crashed coordinator "
        "is respawned)",
    )
    add_output_arguments(parser)
    add_await_arguments(parser)
    parser.add_argument(
        "--no-controllers",
        action="store_true",
        help="wait for no controller: arms follow goals from anyone (no watchdog)",
    )
    parser.add_argument(
        "--endpoint-file",
        help="write the endpoint it listens on to this file once it does (without --listen or "
        "--zenoh-config: a free loopback port)",
    )
    add_sim_snapshot_arguments(parser)
    add_fault_arguments(parser)
    add_bus_arguments(parser)
    return parser


def add_sim_snapshot_arguments(parser: argparse.ArgumentParser) -> None:
    """Snapshots of the run (lockstep): when to take them, where to write them; and a run started from one."""
    parser.add_argument(
        "--snapshot-at", metavar="S,S,...", default="", help="take a snapshot of the run at these sim seconds"
    )
    parser.add_argument("--snapshot-every", type=float, metavar="S", help="take a snapshot every S sim seconds")
    parser.add_argument("--snapshot-dir", metavar="DIR", help="where snapshots are written")
    parser.add_argument("--allocator", default="optimal", help="the coordinator's allocator (written in snapshots)")
    parser.add_argument(
        "--from", dest="from_snapshot", metavar="SNAPSHOT", help="start from the sim's state in a run's snapshot"
    )
    parser.add_argument(
        "--reseed",
        type=int,
        metavar="N",
        help="with --from: the feeders draw arrivals from seed N from the snapshot on (a branch's own arrivals)",
    )


def ticks_at(seconds: str, hz: float) -> set[int]:
    """The ticks of comma-separated sim seconds (`--snapshot-at`, `--pause-at`)."""
    return {round(float(v) * hz) for v in seconds.split(",") if v.strip()}


def attach_snapshots(
    server: SimServer, args: argparse.Namespace, total_ticks: int, original: RunSnapshot | None = None
) -> None:
    """Snapshots due at `--snapshot-at` and every `--snapshot-every` (both in sim seconds), and any asked for while
    the line runs, into `--snapshot-dir`; started from a snapshot (`original`) without either, the snapshots its run
    took later, taken again (written only into a folder given)."""
    hz = server.world.scene_model.control_hz
    at = ticks_at(args.snapshot_at, hz)
    every = round(args.snapshot_every * hz) if args.snapshot_every else 0
    directory = Path(args.snapshot_dir) if args.snapshot_dir else None
    if not (at or every) and original is not None:
        at, every = set(original.later_ticks), original.every_ticks
    if not (at or every or directory):
        return
    facts = RunFacts(
        server.world.scene_model.name, SceneSource.of(args.scene, args.arms, args.seed), args.allocator, total_ticks
    )
    server.snapshots = SimSnapshots(server, facts, directory, at, every)


def restore_from(server: SimServer, snapshot: RunSnapshot, path: str, reseed: int | None = None) -> str:
    """Put the sim back to its state in `snapshot` (read from `path`), then hold until every node says it is back
    too; why it could not ("" when it could)."""
    started = time.monotonic()
    try:
        restore_sim(server, state_of(snapshot, "sim", path))
    except (SnapshotError, StateError) as exc:
        return str(exc)
    if snapshot.mode == "realtime":
        forget_wall_clock_flights(server)
    if reseed is not None:
        server.world.reseed_feeders(reseed)
    if server.snapshots is not None:
        server.snapshots.last_tick = snapshot.tick
    arms = [name for name, link in server.links.items() if not link.lost]
    nodes = (["coordinator"] if server.controls.coordinator else []) + arms
    missing = await_restored(server, snapshot.tick, nodes)
    server.restored_from = {"tick": snapshot.tick, "wall_s": round(time.monotonic() - started, 3)}
    return f"{', '.join(missing)} did not start from the snapshot" if missing else ""


def attach_cameras(server: SimServer, args: argparse.Namespace, session: zenoh.Session, keys: Keys) -> str:
    """The cameras `--cameras` names, rendering into the line; why they cannot ("" when they can, or none asked)."""
    if not args.cameras:
        return ""
    from fleet.sim.cameras.line_cameras import LineCameras, cameras_named  # the renderer only when asked
    from fleet.sim.cameras.rig import CameraMountError, CameraRig
    from fleet.sim.render import RenderUnavailable

    try:
        rig = CameraRig(server.world, cameras_named(server.world.scene_model.cameras, args.cameras))
    except (ValueError, CameraMountError, RenderUnavailable) as exc:
        return str(exc)
    server.cameras = LineCameras(
        rig,
        session,
        keys,
        args.camera_encoding,
        scored=args.perception == "cameras",
        # in lockstep a node that works from the frames waits for each: none may be dropped (a monitor's or a
        # recorder's alone may be, rather than hold the line for a slow viewer)
        every_frame=args.mode == "lockstep" and (args.perception == "cameras" or bool(args.await_eyes)),
    )
    server.cameras.warm_up()  # the renderer's set-up (seconds on a CPU) before the line's first tick, not in it
    return ""


def open_sim_session(args: argparse.Namespace) -> tuple[zenoh.Session, str]:
    """The sim's session, listening (on a free loopback port when asked to say where), and where it listens."""
    endpoints = BusEndpoints.from_args(args)
    if args.endpoint_file and not (endpoints.listen or endpoints.config_file):
        return open_listening_session(endpoints)
    config = make_config(endpoints)
    return zenoh.open(config), ", ".join(json.loads(config.get_json("listen/endpoints")))


def serve(
    server: SimServer, args: argparse.Namespace, stop: StopFlag, ticks: int, audit: RouterAudit | None = None
) -> int:
    """Run the line for `ticks` (once a recorder and a perception process listen, when asked), then write the report
    (with what the router refused all run long, from `audit`); closes the server."""
    if args.record_targets:
        server.target_log = []
    for who, key, timeout_s in (
        ("recorder", server.keys.recorder_ready, args.await_recorder),
        ("perception process", server.keys.seen_ready, args.await_perception),
        ("coordinator's allocator that sees", server.keys.coord("eyes"), args.await_eyes),
    ):
        if timeout_s and not await_ready(server.bus.session, key, timeout_s):
            server.close()
            print(f"sim_server: no {who} said it listens within {timeout_s:.0f} s", file=sys.stderr)
            return 1
    try:
        server.run_ticks(ticks - server.world.tick)
        if not stop.should_stop() and server.world.tick >= ticks:
            server.announce_the_rest()
            server.settle()
    finally:
        if args.record_targets:
            save_target_log(args.record_targets, server.target_log)
        lost = server.stats.coordinator_lost and args.mode == "lockstep"
        why = "the coordinator did not answer within the lockstep timeout" if lost else ""
        report = server.report() | {"stopped_by": stop.reason or why or "duration"}
        if audit is not None:
            report["bus_refused"] = audit.refused()
        server.close()
        write_node_report(args.report, report)
    return 0


def sim_server_of(
    args: argparse.Namespace, world: World, session: zenoh.Session, keys: Keys, stop: StopFlag
) -> SimServer:
    """The server the flags ask for (its mode, its waits, its scheduling, whether poses go out)."""
    server = SimServer(
        world,
        session,
        keys,
        mode=args.mode,
        coordinator=args.coordinator,
        controllers=not args.no_controllers,
        lockstep_timeout_s=args.lockstep_timeout,
        coordinator_timeout_s=args.coordinator_timeout,
        stop=stop,
        speed=args.speed,
    )
    if args.rt:
        server.scheduling = request_realtime_priority("sim_server")
    server.controls.pause_at_ticks = ticks_at(args.pause_at, world.scene_model.control_hz)
    server.outputs.blind = args.perception == "cameras"  # the line's parts are perception's: no poses go out
    return server


def main(argv: list[str] | None = None) -> int:
    opened = node_arguments(build_parser(), argv, "sim_server")
    if opened is None:
        return 2
    args, stop, scene = opened
    try:
        network = network_from_args(args)
    except ValueError as exc:
        print(f"sim_server: {exc}", file=sys.stderr)
        return 2
    if network is not None:
        scene = scene.model_copy(update={"network": network})
    audit = RouterAudit(args.router_audit) if args.router_audit else None
    if audit is not None:  # the one audit of the run: it counts from here to the report
        audit.start()
    session, endpoint = open_sim_session(args)
    keys = Keys(args.run)
    spool = BusSpool(session, keys.recorded(), args.spool, args.run, scene.model_dump_json()) if args.spool else None
    # it listens: whoever waits for the file may connect now (the spool hears them from the first)
    if args.endpoint_file:
        write_text_atomically(args.endpoint_file, endpoint)
    world = World(scene)  # after: the other nodes start and connect while the physics scene is built
    with contextlib.closing(session), contextlib.closing(spool) if spool else contextlib.nullcontext():
        server = sim_server_of(args, world, session, keys, stop)
        server.spool = spool
        why = attach_cameras(server, args, session, keys)
        if why:
            server.close()
            print(f"sim_server: {why}", file=sys.stderr)
            return 2
        ticks = math.ceil(args.duration * scene.control_hz - 1e-9)
        try:
            original = read_snapshot(args.from_snapshot) if args.from_snapshot else None
        except SnapshotError as exc:
            server.close()
            print(f"sim_server: {exc}", file=sys.stderr)
            return 2
        attach_snapshots(server, args, ticks, original)
        if original is not None:
            why = restore_from(server, original, args.from_snapshot, args.reseed)
            if why:
                server.close()
                print(f"sim_server: {why}", file=sys.stderr)
                return 2
        if server.snapshots is not None:
            server.snapshots.build_spare()  # the world the line goes on in after its first snapshot
        return serve(server, args, stop, ticks, audit)


if __name__ == "__main__":
    sys.exit(main())
