"""`fleet run` and `fleet bus-config`: run a line as OS processes and print its summary; write a line's bus configs."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from rich.progress import (
    BarColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
)
from rich.table import Table

from fleet.bus.faults import add_fault_arguments
from fleet.bus.session import add_bus_arguments
from fleet.cli.allocators import allocator_spec
from fleet.cli.errors import (
    UsageError,
    err,
    out,
    output_folder,
    seed_number,
    writable_file,
)
from fleet.cli.ros import checked_rate
from fleet.cli.run_snapshots import (
    add_snapshot_arguments,
    check_snapshot_flags,
    open_snapshot,
    sim_seconds_list,
    snapshot_options,
)
from fleet.common.scene_loading import load_checked_scene
from fleet.monitor.options import add_monitor_arguments, exposure_warning
from fleet.nodes.attached import add_rate_argument
from scenes.yaml_file import DeclarationError

if TYPE_CHECKING:
    from fleet.run.launcher import RunOptions


def check_run_flags(args: argparse.Namespace) -> None:
    """Every `fleet run` flag that cannot work, refused in one line before any process starts."""
    args.allocator = allocator_spec(args.allocator)
    from fleet.bus.faults import network_from_args
    from fleet.cli.bus_flags import check_bus_flags

    if not (math.isfinite(args.duration) and 0 < args.duration <= 7 * 24 * 3600):
        raise UsageError(f"--duration {args.duration:g}: give a positive number of sim seconds (at most a week)")
    if not (math.isfinite(args.speed) and 0.01 <= args.speed <= 100):
        raise UsageError(f"--speed {args.speed:g}: give a factor from 0.01 to 100")
    ports = (("--port", args.port), ("--rosbridge-port", args.rosbridge_port), ("--foxglove-port", args.foxglove_port))
    for flag, port in ports:
        if not 0 <= port <= 65535:
            raise UsageError(f"{flag} {port}: a TCP port is 0 to 65535 (0: any free port)")
    try:
        network_from_args(args)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    check_bus_flags(args)


def arm_list(text: str) -> tuple[str, ...]:
    """`--ros-arms`' value: arm ids separated by commas (argparse's `type`)."""
    arms = tuple(a.strip() for a in text.split(",") if a.strip())
    if not arms:
        raise argparse.ArgumentTypeError(f"{text!r}: give arm ids separated by commas, e.g. arm_0,arm_1")
    return arms


def check_ros2_flags(args: argparse.Namespace, arms: list[str]) -> None:
    """`--ros-domain-id` a ROS domain; `--ros-arms` needs `--ros2` and names only the line's arms."""
    if not 0 <= args.ros_domain_id <= 232:
        raise UsageError(f"--ros-domain-id {args.ros_domain_id}: ROS domains are 0 to 232")
    if args.ros_arms is None:
        return
    if not args.ros2:
        raise UsageError("--ros-arms needs --ros2 (it says which arms an outside ROS 2 stack may drive)")
    unknown = [a for a in args.ros_arms if a not in arms]
    if unknown:
        raise UsageError(f"--ros-arms: {', '.join(unknown)} not in this line (its arms: {', '.join(arms)})")


def check_placement_flags(args: argparse.Namespace) -> None:
    """`--bus-config` and `--hosts`: readable, written for this scene's arms, namespaces that exist; one line if not."""
    from fleet.bus.bus_config import BusConfigError
    from fleet.run.launcher import placement

    if args.hosts and not args.bus_config:
        raise UsageError(
            "--hosts needs --bus-config: nodes in other namespaces reach each other only through the sim's router"
        )
    if args.bus_config and (args.listen or args.connect or args.zenoh_config):
        raise UsageError(
            "--bus-config says where every node listens or connects: leave out --listen, --connect and --zenoh-config"
        )
    try:
        placement(args.bus_config, args.hosts, load_checked_scene(args.scene, arms=args.arms))
    except (BusConfigError, DeclarationError) as exc:
        raise UsageError(str(exc)) from None


def cmd_bus_config(args: argparse.Namespace) -> int:
    from fleet.bus.bus_config import BusConfigError, write_bus_configs

    arms = [a.name for a in load_checked_scene(args.scene, arms=args.arms).arms]
    check_ros2_flags(args, arms)
    output_folder("--out", args.out, parents=True)
    try:
        ros = {"ros_domain": args.ros_domain_id, "ros_arms": args.ros_arms} if args.ros2 else {}
        made = write_bus_configs(args.out, args.address, args.port, arms, secure=not args.insecure, **ros)
    except BusConfigError as exc:
        raise UsageError(str(exc)) from None
    how = "TLS, a login per node, access control" if made.secure else "plain TCP, no logins (a trusted network only)"
    print(
        f"wrote the bus configs of {len(arms)} arm(s) to {made.directory}: the sim listens on {made.endpoint} ({how})"
    )
    print(
        f"run it: fleet run {args.scene} --bus-config {made.directory} [--hosts HOSTS.yaml]; or start each node with "
        f"--zenoh-config {made.directory}/<node>.json5"
    )
    return 0


def run_recording(args: argparse.Namespace) -> str | None:
    """Where `fleet run` records: `--record FILE`, else `DIR/recording.mcap` with `--out DIR`, else nowhere."""
    if args.out:
        output_folder("--out", args.out, parents=False)
    if args.summary:
        writable_file("--summary", args.summary)
    if args.record:
        return str(writable_file("--record", args.record))
    return str(Path(args.out) / "recording.mcap") if args.out else None


def run_options(args: argparse.Namespace) -> RunOptions:
    """`fleet run`'s flags as the launcher's options."""
    from fleet.run.launcher import RunOptions

    return RunOptions(
        scene=args.scene,
        arms=args.arms,
        duration_s=args.duration,
        mode=args.mode,
        speed=args.speed,
        pause_at=args.pause_at,
        seed=args.seed,
        respawn=args.respawn,
        realtime_priority=args.rt,
        run_id=args.run_id,
        keep_logs=args.keep_logs,
        allocator=args.allocator,
        pipeline=args.pipeline,
        listen=(args.listen or [None])[0],
        connect=tuple(args.connect or ()),
        zenoh_config=args.zenoh_config,
        monitor=args.monitor,
        monitor_host=args.host,
        monitor_port=args.port,
        rosbridge_port=args.rosbridge_port if args.rosbridge else None,
        foxglove_port=args.foxglove_port if args.foxglove else None,
        ros2_domain=args.ros_domain_id if args.ros2 else None,
        ros2_arms=args.ros_arms,
        ros_max_rate_hz=checked_rate(args.ros_max_rate_hz, "--ros-max-rate-hz"),
        record=run_recording(args),
        cameras=args.cameras,
        camera_encoding=args.camera_encoding,
        perception=args.perception,
        latency_ms=args.latency_ms,
        jitter_ms=args.jitter_ms,
        loss=args.loss,
        bus_config=args.bus_config,
        hosts=args.hosts,
        insecure=args.insecure,
        **snapshot_options(args),
    )


# the logins a user hands to a client of their own, and what each may do (`docs/running.md`, access control)
CLIENT_LOGINS = {
    "monitor": "watch, e-stop, pause, respawn",
    "recorder": "listen only",
    "ros_client": "an outside ROS 2 stack on rmw_zenoh, with --ros2",
}


def bus_line(launcher, run_id: str) -> str:
    """Where the run's bus is and how to watch it: with the monitor's login on a secure bus, else by its endpoint;
    on a secure bus, every client login's config file and what it may do (the line's own processes have theirs)."""
    if launcher.bus is None:
        return f"bus: {launcher.endpoint} (watch it: fleet monitor --connect {launcher.endpoint} --run {run_id})"
    how = "TLS, a login per node, access control" if launcher.bus.secure else "no logins"
    folder = launcher.bus.directory
    logins = [f"{n}.json5 ({what})" for n, what in CLIENT_LOGINS.items() if (folder / f"{n}.json5").exists()]
    return (
        f"bus: {launcher.endpoint} ({how}; watch it: fleet monitor --zenoh-config "
        f"{launcher.bus.config_for('monitor')} --run {run_id})\n"
        f"logins in {folder}: {', '.join(logins)}; the line's own processes have one each"
    )


def check_camera_flags(args: argparse.Namespace, scene) -> None:
    """`--cameras` names cameras the scene has, on a machine that can render them: else one line, before anything
    starts. `--perception cameras` renders every fixed camera of the scene (the line sees through all of them),
    besides those `--cameras` names."""
    from coordinator.allocator_plugins import sees

    allocator = getattr(args, "allocator", None)
    if args.perception == "cameras" or sees(allocator):
        fixed = [c.name for c in scene.cameras if c.arm is None]
        what = "--perception cameras" if args.perception == "cameras" else f"--allocator {allocator} (it sees)"
        if not fixed:
            raise UsageError(f"{what}: the scene {scene.name} has no fixed camera (docs/cameras.md)")
        if not args.cameras:
            args.cameras = ",".join(fixed)  # checked below: a machine that cannot render is refused in one line
    if not args.cameras:
        return
    from fleet.sim.cameras.line_cameras import cameras_named  # the renderer only when asked
    from fleet.sim.render import RenderUnavailable, require_render

    try:
        cameras_named(scene.cameras, args.cameras)
        require_render()
    except (ValueError, RenderUnavailable) as exc:
        raise UsageError(str(exc)) from None


def cmd_run(args: argparse.Namespace) -> int:
    folder = open_snapshot(args)
    try:
        return _run(args)
    finally:
        if folder is not None:
            folder.cleanup()


def _run(args: argparse.Namespace) -> int:
    from fleet.run.disk_watch import room_problem
    from fleet.run.launcher import Launcher

    check_run_flags(args)
    check_snapshot_flags(args)
    scene = load_checked_scene(args.scene, arms=args.arms)  # a bad scene: one line, before anything starts
    check_ros2_flags(args, [a.name for a in scene.arms])
    check_camera_flags(args, scene)
    check_placement_flags(args)
    options = run_options(args)
    if short := room_problem(options.record):
        raise UsageError(short)
    if args.insecure:
        err.print(
            "warning: --insecure: no logins and no access control on the bus; any local process can command the line",
            style="bold yellow",
            markup=False,
            highlight=False,
        )
    if args.monitor:
        warning = exposure_warning(args.host)
        if warning:
            err.print(warning, style="bold yellow", markup=False, highlight=False)
    with Progress(
        TextColumn("[bold]{task.fields[scene]}"),
        BarColumn(),
        TextColumn("sim {task.completed:.1f}/{task.total:.0f} s"),
        TextColumn("parts {task.fields[done]}/{task.fields[spawned]} done, {task.fields[rate]:.1f}/min"),
        TimeElapsedColumn(),
        console=err,
        transient=False,
    ) as progress:
        bar = progress.add_task("run", total=args.duration, scene=args.scene_label, done=0, spawned=0, rate=0.0)

        def on_progress(p) -> None:
            rate = p.parts_completed / (p.sim_time_s / 60) if p.sim_time_s > 0 else 0.0
            progress.update(bar, completed=p.sim_time_s, done=p.parts_completed, spawned=p.parts_spawned, rate=rate)

        with Launcher(
            options, on_progress, on_message=lambda text: progress.console.print(text, markup=False, highlight=False)
        ) as launcher:
            progress.console.print(bus_line(launcher, args.run_id), markup=False, highlight=False)
            summary = launcher.run()
            if args.keep_logs:
                err.print(f"logs and reports kept in {launcher.dir}")
        progress.update(
            bar, completed=summary["sim_seconds"], done=summary["parts_completed"], spawned=summary["parts_spawned"]
        )
    print_run_summary(summary)
    if args.out:
        write_run_artefacts(summary, Path(args.out))
    if args.summary:
        Path(args.summary).write_text(json.dumps(summary, indent=1) + "\n")
    if args.json:
        print(json.dumps(summary))
    if summary["status"] == "error":
        print(f"fleet: error: {summary['error']}", file=sys.stderr)
        return 1
    return 130 if summary["status"] == "interrupted" else 0


def write_run_artefacts(summary: dict, out_dir: Path) -> None:
    """`fleet run --out DIR`: the summary, and the time series and plots made from the run's recording."""
    from fleet.record.mcap_file import Recording
    from fleet.record.report import series_from_recording, write_report

    (out_dir / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    if (summary.get("recording") or {}).get("file"):
        written = write_report(series_from_recording(Recording(summary["recording"]["file"])), out_dir)
        err.print(
            f"artefacts in {out_dir}: summary.json, {Path(summary['recording']['file']).name}, "
            f"{', '.join(p.name for p in written)}",
            markup=False,
            highlight=False,
        )
    else:
        err.print(f"the recorder wrote nothing: only summary.json in {out_dir}", markup=False, highlight=False)


def _camera_row(c: dict) -> str:
    frames = ", ".join(f"{name} {n}" for name, n in c["frames_by_camera"].items())
    return (
        f"{frames} / {c['images']} images, {c['bytes_out'] / 1e6:.1f} MB / {c['render_s']:.1f} s "
        f"(the first frame {c['first_frame_s']:.1f} s), encoding {c['encode_s']:.1f} s"
    )


def _seen_row(p: dict) -> str:
    """What seeing cost (`--perception cameras`): the seen parts' error against the truth, recall, the grasps that
    held, and how old the frames decisions worked from were."""
    scored, picks, coord = p.get("scored") or {}, p.get("picks") or {}, p.get("coordinator") or {}
    held = f"{picks.get('done', 0)}/{picks.get('done', 0) + picks.get('grasp_missed', 0)}"
    return (
        f"{scored.get('position_error_p50_mm')} / {scored.get('position_error_p95_mm')}, "
        f"{scored.get('recall')}, {held} (decisions on frames {coord.get('latency_p95_frames')} frames old at p95)"
    )


def print_run_summary(s: dict) -> None:
    table = Table(
        "figure", "value", title=f"{s['scene']}: {s['arms']} arms, {s['mode']}, seed {s['seed']} ({s['status']})"
    )
    rows = [
        ("sim / wall seconds", f"{s['sim_seconds']:.1f} / {s['wall_seconds']:.1f}"),
        ("parts spawned / completed", f"{s['parts_spawned']} / {s['parts_completed']}"),
        (
            "missed / failed / on the line",
            f"{s['parts_missed']} / {s['parts_failed']} / {s['parts_in_progress']}"
            + (f" ({n} set down at a buffer)" if (n := s.get("parts_buffered")) else ""),
        ),
        ("throughput (per sim minute)", f"{s['throughput_per_min']:.2f}"),
        ("allocator", _allocator_row(s)),
        (
            "nominal bound (per minute, the scene's rates)",
            "-"
            if s.get("throughput_bound_per_min") is None
            else f"{s['throughput_bound_per_min']:.2f}, limited by {s['bottleneck']['name']}",
        ),
        (
            "this run's bound (per minute, its own arrivals)",
            "-"
            if not s.get("run_bound_per_min")
            else f"{s['run_bound_per_min']:.2f}: {_share(s['run_bound_fraction'])} of it achieved; "
            f"{s['parts_completed']} of {s['parts_finishable']} parts that arrived in time to be finished"
            + _completable(s),
        ),
        (
            "arms: working / waiting for a grant (+ held at a fixture) / idle",
            "; ".join(
                f"{a} {t['working']:.0%} / "
                f"{t['waiting_for_grant']:.0%}{f' (+{held:.0%})' if (held := t.get('held_at_fixture', 0)) else ''} "
                f"/ {t['idle']:.0%}"
                for a, t in s.get("arm_time", {}).items()
            )
            or "-",
        ),
        ("inter-arm contacts (ticks)", str(s["inter_arm_contacts"])),
        ("min separation (m)", "-" if s["min_separation_m"] is None else f"{s['min_separation_m']:.3f}"),
        ("grants denied", str(s["grants_denied"])),
        ("refused by the plant's safety / stopped", _safety_row(s)),
        ("round trip p50 / p99 (ms)", f"{s['latency_p50_ms']} / {s['latency_p99_ms']}"),
        ("dropped messages", str(s["dropped_messages"])),
        ("refused by the router", _router_row(s.get("bus_refused"))),
        ("arms lost / respawns", f"{', '.join(s['arms_lost']) or 'none'} / {s['respawns']}"),
    ]
    for row in rows + _rows_when_present(s):
        table.add_row(*row)
    out.print(table)


def _rows_when_present(s: dict) -> list[tuple[str, str]]:
    """The summary's rows of what only some runs have: a realtime clock, a restore, snapshots, cameras, perception."""
    rows = []
    if s.get("realtime_clock"):
        rows.append(
            ("realtime clock: sim s per wall s / ticks late p50, p99, worst (ms)", _clock_row(s["realtime_clock"]))
        )
    if s.get("restored_from"):
        r = s["restored_from"]
        rows.append(("restored from a snapshot", f"tick {r['tick']}, every process back in {r['wall_s']:.2f} s"))
    if s.get("snapshots") or s.get("snapshots_failed") or s.get("snapshots_refused"):
        rows.append(("snapshots (written / failed / refused)", _snapshot_row(s)))
    if s.get("cameras"):
        rows.append(("cameras: frames / on the bus / rendering", _camera_row(s["cameras"])))
    if s.get("perception"):
        rows.append(("seen: error p50 / p95 (mm), recall, grasps held", _seen_row(s["perception"])))
    return rows


def _clock_row(clock: dict) -> str:
    """The realtime clock kept: the factor against the speed asked, and how late the sim's ticks started."""
    if clock.get("rtf") is None:
        return "-"
    late = clock.get("sim_tick_late_ms") or {}
    spread = " / ".join(f"{late[k]:.1f}" for k in ("p50", "p99", "worst")) if late else "-"
    return f"{clock['rtf']:.3f} of {clock['speed']:g} asked ({clock['rtf_error']:+.1%}) / {spread}"


def _snapshot_row(s: dict) -> str:
    """The snapshots written and failed, the longest the line stood still for one, and (lockstep) how much longer
    the ticks after one took at most while the nodes wrote their states."""
    stall, after = s.get("snapshot_stall_ms_max"), s.get("snapshot_next_ticks_ms_max")
    held = ""
    if stall:
        after_row = f"; ticks after it {after} ms slower at most" if after is not None else ""
        held = f" (line held {stall} ms at most{after_row})"
    return f"{len(s['snapshots'])} / {len(s['snapshots_failed'])} / {len(s.get('snapshots_refused') or [])}{held}"


def _router_row(refused: dict | None) -> str:
    """What the run's router refused: a total and the commonest kind, or why there is no count."""
    if refused is None:
        return "- (not counted: no secure bus of the run's own)"
    if not refused:
        return "0"
    top = max(refused, key=refused.get)
    return f"{sum(refused.values())} (most: {top}, {refused[top]})"


def _completable(s: dict) -> str:
    """How many of a run's finishable parts it could complete at most, where fewer (an assembly pairs its parts)."""
    n, of = s.get("parts_completable"), s.get("parts_finishable")
    if n is None or of is None or n >= of:
        return ""
    return f", {n} of them could be completed (limited by {(s.get('capacity_of_run') or {}).get('bottleneck', '?')})"


def _allocator_row(s: dict) -> str:
    """The allocator, and a plug-in's decisions greedy took instead (raised, invalid, overran)."""
    faults = s.get("allocator_faults") or {}
    said = ", ".join(f"{kind} {n}" for kind, n in sorted(faults.items()))
    return f"{s.get('allocator')}" + (f" (decisions greedy took instead: {said})" if said else "")


def _share(fraction: float | None) -> str:
    """A fraction as a percentage, or "-" where there is none (a bound of 0: nothing could be done)."""
    return "-" if fraction is None else f"{fraction:.0%}"


def _safety_row(s: dict) -> str:
    """Goals the plant refused (by kind) and motions it stopped."""
    refused = s.get("safety_refused_goals", {})
    kinds = "".join(f", {n} {k}" for k, n in refused.items())
    return f"{sum(refused.values())} goals{kinds} / {s.get('safety_stops', 0)}"


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """This group's sub-commands."""
    _add_run(sub)
    _add_bus_config(sub)


def _add_run(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="run the line: sim server, coordinator and one controller per arm as processes")
    p.add_argument("scene", nargs="?", help="bundled scene name or scene file (default assembly_line)")
    p.add_argument("--arms", type=int, default=None, help="arm count for scenes with an arm row")
    p.add_argument("--duration", type=float, default=None, help="sim seconds to run (default 120)")
    _add_clock_arguments(p)
    p.add_argument("--seed", type=seed_number, default=None, help="overrides the scene's seed")
    p.add_argument(
        "--respawn",
        action="store_true",
        help="restart a controller or the coordinator that dies (a new coordinator takes over the line)",
    )
    p.add_argument(
        "--allocator",
        help="how tasks go to arms: optimal (default; with --from, the snapshot's), auction, greedy, an installed "
        "plug-in, package.module:Name, or policy:FILE of a trained policy (`fleet allocators`)",
    )
    p.add_argument(
        "--no-pipeline",
        dest="pipeline",
        action="store_false",
        help=(
            "give a fixture's next part to an arm only once the fixture is ready for it (default: before, the arm "
            "held at the edge)"
        ),
    )
    p.add_argument(
        "--rt",
        action="store_true",
        help="real-time scheduling (SCHED_FIFO) for the controllers and, in realtime, the sim's loop; a warning where "
        "the OS refuses it",
    )
    p.add_argument("--run-id", default="line", help="keeps several lines on one Zenoh network apart")
    p.add_argument("--summary", metavar="FILE", help="also write the summary JSON here")
    p.add_argument("--keep-logs", action="store_true", help="keep each process's log and report (the path is printed)")
    p.add_argument("--json", action="store_true", help="last stdout line: the summary as one JSON object")
    p.add_argument(
        "--monitor", action="store_true", help="serve the browser monitor (Viser) of this run; see --host/--port"
    )
    p.add_argument(
        "--record",
        metavar="FILE.mcap",
        help="record every bus message, TF, joint states and markers (rosbag2-layout MCAP)",
    )
    p.add_argument(
        "--out",
        metavar="DIR",
        help="write the run's artefacts here: summary.json, recording.mcap, time series CSV, plots",
    )
    _add_camera_arguments(p)
    add_snapshot_arguments(p)
    _add_placement_arguments(p)
    _add_rosbridge_arguments(p)
    add_monitor_arguments(p)
    add_fault_arguments(p)
    add_bus_arguments(p)
    p.set_defaults(func=cmd_run)


def _add_clock_arguments(p: argparse.ArgumentParser) -> None:
    """The line's clock: `--mode`, `--speed`, `--pause-at`."""
    p.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep")
    p.add_argument("--speed", type=float, default=1.0, help="realtime: speed factor against the wall clock")
    p.add_argument(
        "--pause-at",
        type=sim_seconds_list,
        metavar="S,S,...",
        default=(),
        help="pause the line once its tick at these sim seconds has run (its views out: ROS's /clock reads S), "
        "until resumed (the monitor, ROS's /resume): in lockstep, what a user sends meanwhile lands at one tick in "
        "every run",
    )


def _add_camera_arguments(p: argparse.ArgumentParser) -> None:
    """Rendering the scene's cameras into the line: `--cameras`, `--camera-encoding`."""
    p.add_argument(
        "--cameras",
        nargs="?",
        const="all",
        metavar="NAMES",
        help="render the scene's cameras (all, or names joined by commas) at their rates; images go on the bus, into "
        "the recording and to ROS (docs/cameras.md)",
    )
    p.add_argument(
        "--perception",
        choices=("truth", "cameras"),
        default="truth",
        help="cameras: the line works from what its fixed cameras show (all rendered): a perception node detects "
        "and tracks the parts, and the coordinator and the controllers see only its parts; the sim's truth only "
        "scores it (docs/perception.md)",
    )
    p.add_argument(
        "--camera-encoding",
        choices=("auto", "png", "jpeg", "raw"),
        default="auto",
        help="how RGB images travel on the bus (default auto: raw arrays where every node runs here on the run's own "
        "bus, png where the bus may cross a network); recordings and ROS get compressed images either way",
    )


def _add_rosbridge_arguments(p: argparse.ArgumentParser) -> None:
    """Serving the run to ROS tools: `--rosbridge`, `--rosbridge-port`."""
    p.add_argument(
        "--rosbridge",
        action="store_true",
        help="serve the line to ROS tools (roslibpy, roslibjs, Foxglove) over rosbridge's WebSocket; docs/ros2.md",
    )
    p.add_argument(
        "--rosbridge-port", type=int, default=9090, metavar="PORT", help="the rosbridge server's port (default 9090)"
    )
    p.add_argument(
        "--foxglove",
        action="store_true",
        help="serve the line to the Foxglove app over its own WebSocket protocol (loopback); docs/ros2.md",
    )
    p.add_argument(
        "--foxglove-port", type=int, default=8765, metavar="PORT", help="the Foxglove server's port (default 8765)"
    )
    _add_ros2_arguments(p)
    add_rate_argument(p, "--ros-max-rate-hz")


def _add_ros2_arguments(p: argparse.ArgumentParser) -> None:
    """The line's native ROS 2 graph: `--ros2`, `--ros-domain-id`, `--ros-arms`."""
    p.add_argument(
        "--ros2",
        action="store_true",
        help="the line's ROS 2 topics, services and actions natively on its router (rmw_zenoh's layout); docs/ros2.md",
    )
    p.add_argument("--ros-domain-id", type=int, default=0, metavar="N", help="ROS_DOMAIN_ID for --ros2 (default 0)")
    p.add_argument(
        "--ros-arms",
        type=arm_list,
        metavar="ARM,...",
        help="with --ros2: the arms an outside ROS 2 stack (login ros_client) may drive (default: every arm; pause "
        "and resume only with every arm)",
    )


def _add_placement_arguments(p: argparse.ArgumentParser) -> None:
    """Where a run's nodes meet and start: `--bus-config`, `--hosts`."""
    p.add_argument(
        "--insecure",
        action="store_true",
        help="a plain bus on loopback, no logins and no access control (by default a run makes its own: TLS, a login "
        "per node, access control; `fleet monitor` then joins with the config the run prints)",
    )
    p.add_argument(
        "--bus-config",
        metavar="DIR",
        help="the line's bus from `fleet bus-config`: the sim a router, every node logged in "
        "with its own config (TLS, passwords, access control)",
    )
    p.add_argument(
        "--hosts",
        metavar="FILE",
        help="the network namespace each node starts in (YAML `nodes: {sim: NS, ...}`; needs --bus-config)",
    )


def _add_bus_config(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bus-config",
        help=(
            "write one Zenoh config per node for a line across hosts: the sim a router with TLS, logins and access "
            "control"
        ),
    )
    p.add_argument("--address", required=True, help="the IP address of the sim's host, as the other hosts reach it")
    p.add_argument("--port", type=int, default=7447, help="the port the sim's router listens on (default 7447)")
    p.add_argument(
        "--scene", default="assembly_line", help="the scene whose arms get a login each (default assembly_line)"
    )
    p.add_argument("--arms", type=int, default=None, help="arm count for scenes with an arm row")
    p.add_argument(
        "--insecure",
        action="store_true",
        help="plain TCP: no TLS, no logins, no access control (a trusted network only)",
    )
    p.add_argument(
        "--out",
        metavar="DIR",
        required=True,
        help="where to write the configs (keys and passwords readable by you only)",
    )
    _add_ros2_arguments(p)
    p.set_defaults(func=cmd_bus_config)
