"""The `fleet` command line: run, check, scenes, robots, trials and benchmarks.

Errors a user can cause (a bad scene, an unknown robot, a missing extra) end
with one readable line on stderr and exit status 2, never a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import json
import os
import re
import math
import sys
from collections.abc import Sequence
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from fleet.bus.faults import add_fault_arguments
from fleet.bus.session import add_bus_arguments
from fleet.monitor.options import add_monitor_arguments, exposure_warning
from robots.registry import (
    MissingModelsError,
    UnknownRobotError,
    declared_robots,
    entry_point_problems,
    get_robot,
    is_available,
    register_file,
)
from fleet.scene_loading import load_scene
from scenes.loader import bundled_scene_names, first_error
from scenes.yaml_file import DeclarationError

class UsageError(ValueError):
    """A flag that cannot work: one line, exit 2, before anything starts."""


def user_errors() -> tuple[type[BaseException], ...]:
    """Errors a user causes: one line, exit 2 (a bad recording's only once the recording module is loaded: it imports mcap)."""
    errors: tuple[type[BaseException], ...] = (DeclarationError, UnknownRobotError, MissingModelsError, UsageError)
    recording = sys.modules.get("fleet.record.mcap_file")
    return errors + ((recording.RecordingError,) if recording else ())
out = Console()
err = Console(stderr=True)


def cmd_check(args: argparse.Namespace) -> int:
    from coordinator.capacity import capacity_bound

    scene = load_scene(args.file, arms=args.arms)
    print("ok")
    print(capacity_line(capacity_bound(scene)))
    return 0


def capacity_line(bound) -> str:
    """The capacity bound in one line: what the line could complete at best, and what limits it."""
    text = f"capacity: at best {bound.throughput_bound_per_min:.2f} parts/min of {bound.arrivals_per_min:.2f} arriving"
    if bound.bottleneck == "arrivals":
        text += f" (the line can take them all; busiest: {bound.busiest or '-'} {bound.bottleneck_busy_fraction:.0%} of the time)"
    else:
        text += f" (bottleneck: {bound.bottleneck}, busy all the time)"
    if bound.unservable:
        text += f"; no arm can serve {', '.join(bound.unservable)}"
    return text


def cmd_scenes(args: argparse.Namespace) -> int:
    table = Table("scene", "arms", "description")
    for name in bundled_scene_names():
        scene = load_scene(name)
        table.add_row(name, str(len(scene.arms)), scene.description)
    out.print(table)
    return 0


def robot_uid(name_or_file: str) -> str:
    """A registered robot's uid, or the uid of the robot a YAML file declares (registered here)."""
    path = Path(name_or_file)
    if path.suffix in (".yaml", ".yml") or path.exists():
        return register_file(path).uid
    return get_robot(name_or_file).uid


def cmd_robots(args: argparse.Namespace) -> int:
    if args.check:
        return check_robot_lines(robot_uid(args.check), args.trials, args.seed)
    table = Table("robot", "arm DoF", "gripper DoF", "reach (m)", "available", "declared in", "summary")
    for spec in declared_robots():
        uid = spec.uid
        available = "yes" if is_available(uid) else f"needs the '{spec.needs_extra}' extra"
        table.add_row(uid, str(spec.arm_dof), str(len(spec.gripper_joints)), f"{spec.reach_m:.2f}", available,
                      spec.declared_in, spec.summary)
    out.print(table)
    for problem in entry_point_problems():
        err.print(f"problem: {problem}", markup=False, highlight=False)
    return 0


def check_robot_lines(uid: str, trials: int, seed: int) -> int:
    """`fleet robots --check`: one plain line per check; exit 1 when any found a problem."""
    from fleet.robot_check import check_robot

    if trials < 0:
        raise UsageError(f"--trials {trials}: give 0 or more")
    spec = get_robot(uid)
    print(f"{uid}: {spec.arm_dof}-DoF arm, {len(spec.gripper_joints)} gripper joint(s), declared in {spec.declared_in}", flush=True)
    problems = 0
    for finding in check_robot(spec, trials, seed):
        problems += not finding.ok
        print(finding.line(), flush=True)
    print(f"{uid}: {'no problems found' if problems == 0 else f'{problems} problem(s)'}")
    return 0 if problems == 0 else 1


def cmd_tune(args: argparse.Namespace) -> int:
    """`fleet tune`: a seeded search over a robot's gains and pick timing, each candidate judged by pick trials."""
    from fleet.tuning import search

    uid = robot_uid(args.robot)
    if args.candidates < 1 or args.trials < 1:
        raise UsageError("--candidates and --trials must be at least 1")
    spec = get_robot(uid)
    with Progress(TextColumn(f"{uid} tuning"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(), console=err) as progress:
        bar = progress.add_task("tune", total=args.candidates)
        results = search(uid, args.candidates, args.trials, args.seed, lambda _t: progress.update(bar, advance=1))
    names = list(results[0].candidate.describe(spec))
    table = Table("rank", "placed", "sim s / trial", *names, title=f"{uid}: {args.candidates} settings x {args.trials} trials (seed {args.seed})")
    for rank, tried in enumerate(results, 1):
        values = tried.candidate.describe(spec)
        mark = " (registered)" if tried.candidate == type(tried.candidate)() else ""
        table.add_row(f"{rank}{mark}", f"{tried.successes}/{tried.trials}", f"{tried.mean_sim_s:.2f}", *(f"{values[n]:g}" for n in names))
    out.print(table)
    best = results[0]
    for line in best.failures:
        err.print(f"  best setting failed: {line}", markup=False, highlight=False)
    if args.json:
        print(json.dumps({"robot": uid, "trials": args.trials, "seed": args.seed,
                          "results": [{"successes": t.successes, "mean_sim_s": t.mean_sim_s, **t.candidate.describe(spec)} for t in results]}))
    return 0


def cmd_trials(args: argparse.Namespace) -> int:
    from pydantic import ValidationError

    from fleet.trials import run_trials, trial_scene

    args.robot = robot_uid(args.robot)
    if args.trials < 1:
        raise SystemExit("fleet: error: --trials must be at least 1")
    try:
        scene = trial_scene(args.robot, args.seed, args.physics_hz, args.solver_iterations)
    except ValidationError as exc:
        raise UsageError("{}: {}".format(*first_error(exc, top="scene"))) from None
    failures: list[str] = []
    with Progress(
        TextColumn(f"{args.robot} trials"), BarColumn(), MofNCompleteColumn(),
        TextColumn("{task.fields[ok]} ok"), TimeElapsedColumn(), console=err, transient=False,
    ) as progress:
        bar = progress.add_task("trials", total=args.trials, ok=0)
        ok = 0

        def on_result(result) -> None:
            nonlocal ok
            ok += result.success
            if not result.success:
                failures.append(f"seed {result.seed}: {result.phase}: {result.reason}")
            progress.update(bar, advance=1, ok=ok)

        results = run_trials(args.robot, args.trials, args.seed, on_result, args.physics_hz, args.solver_iterations)
    successes = sum(r.success for r in results)
    summary = {"robot": args.robot, "trials": len(results), "successes": successes, "success_rate": successes / len(results),
               "physics_hz": scene.physics_hz, "solver_iterations": scene.solver_position_iterations}
    for line in failures:
        err.print(f"  failed: {line}")
    out.print(f"{args.robot}: {successes}/{len(results)} picks placed, success rate {summary['success_rate']:.2f}")
    if args.json:
        print(json.dumps(summary))
    return 0


def check_run_flags(args: argparse.Namespace) -> None:
    """Every `fleet run` flag that cannot work, refused in one line before any process starts."""
    from fleet.bus.faults import network_from_args
    from fleet.bus.keys import Keys
    from fleet.bus.session import BusEndpoints, make_config

    if not (math.isfinite(args.duration) and 0 < args.duration <= 7 * 24 * 3600):
        raise UsageError(f"--duration {args.duration:g}: give a positive number of sim seconds (at most a week)")
    if not (math.isfinite(args.speed) and 0.01 <= args.speed <= 100):
        raise UsageError(f"--speed {args.speed:g}: give a factor from 0.01 to 100")
    if not 0 <= args.port <= 65535:
        raise UsageError(f"--port {args.port}: a TCP port is 0 to 65535 (0: any free port)")
    try:
        network_from_args(args)
    except ValueError as exc:
        raise UsageError(str(exc)) from None
    try:
        Keys(args.run_id)
    except ValueError as exc:
        raise UsageError(f"--run-id: {exc}") from None
    if args.zenoh_config and not Path(args.zenoh_config).is_file():
        raise UsageError(f"--zenoh-config {args.zenoh_config}: not a readable file")
    for flag, endpoints in (("--listen", args.listen or ()), ("--connect", args.connect or ())):
        for ep in endpoints:
            proto, _, rest = ep.partition("/")
            if proto not in ("tcp", "udp", "tls", "quic", "unixsock-stream", "ws") or not rest:
                raise UsageError(f"{flag} {ep!r}: an endpoint looks like tcp/127.0.0.1:7447")
    try:
        make_config(BusEndpoints(tuple(args.listen or ()), tuple(args.connect or ()), args.zenoh_config))
    except Exception as exc:  # zenoh's own parser: keep its message, not its source locations
        said = re.search(r'msg: "([^"]*)"', str(exc))
        text = re.sub(r"\s+at /\S+", "", said.group(1) if said else (str(exc).splitlines() or [type(exc).__name__])[0])
        raise UsageError(f"bus flags: {text}") from None


def check_placement_flags(args: argparse.Namespace) -> None:
    """`--bus-config` and `--hosts`: readable, written for this scene's arms, namespaces that exist; one line if not."""
    from fleet.bus.bus_config import BusConfigError
    from fleet.launcher import placement

    if args.hosts and not args.bus_config:
        raise UsageError("--hosts needs --bus-config: nodes in other namespaces reach each other only through the sim's router")
    if args.bus_config and (args.listen or args.connect or args.zenoh_config):
        raise UsageError("--bus-config says where every node listens or connects: leave out --listen, --connect and --zenoh-config")
    try:
        placement(args.bus_config, args.hosts, load_scene(args.scene, arms=args.arms))
    except (BusConfigError, DeclarationError) as exc:
        raise UsageError(str(exc)) from None


def cmd_bus_config(args: argparse.Namespace) -> int:
    from fleet.bus.bus_config import BusConfigError, write_bus_configs

    arms = [a.name for a in load_scene(args.scene, arms=args.arms).arms]
    output_folder("--out", args.out, parents=True)
    try:
        made = write_bus_configs(args.out, args.address, args.port, arms, secure=not args.insecure)
    except BusConfigError as exc:
        raise UsageError(str(exc)) from None
    how = "TLS, a login per node, access control" if made.secure else "plain TCP, no logins (a trusted network only)"
    print(f"wrote the bus configs of {len(arms)} arm(s) to {made.directory}: the sim listens on {made.endpoint} ({how})")
    print(f"run it: fleet run {args.scene} --bus-config {made.directory} [--hosts HOSTS.yaml]; or start each node with "
          f"--zenoh-config {made.directory}/<node>.json5")
    return 0


def run_recording(args: argparse.Namespace) -> str | None:
    """Where `fleet run` records: `--record FILE`, else `DIR/recording.mcap` with `--out DIR`, else nowhere."""
    if args.out:
        output_folder("--out", args.out, parents=False)
    if args.record:
        return str(writable_file("--record", args.record))
    return str(Path(args.out) / "recording.mcap") if args.out else None


def cmd_run(args: argparse.Namespace) -> int:
    from fleet.launcher import Launcher, RunOptions

    check_run_flags(args)
    load_scene(args.scene, arms=args.arms)  # a bad scene: one line, before anything starts
    check_placement_flags(args)
    options = RunOptions(
        scene=args.scene, arms=args.arms, duration_s=args.duration, mode=args.mode, speed=args.speed, seed=args.seed,
        respawn=args.respawn, realtime_priority=args.rt, run_id=args.run_id, keep_logs=args.keep_logs, allocator=args.allocator, pipeline=args.pipeline,
        listen=(args.listen or [None])[0], connect=tuple(args.connect or ()), zenoh_config=args.zenoh_config,
        monitor=args.monitor, monitor_host=args.host, monitor_port=args.port, record=run_recording(args),
        latency_ms=args.latency_ms, jitter_ms=args.jitter_ms, loss=args.loss, bus_config=args.bus_config, hosts=args.hosts,
    )
    if args.monitor:
        warning = exposure_warning(args.host)
        if warning:
            err.print(warning, style="bold yellow", markup=False, highlight=False)
    with Progress(
        TextColumn("[bold]{task.fields[scene]}"), BarColumn(), TextColumn("sim {task.completed:.1f}/{task.total:.0f} s"),
        TextColumn("parts {task.fields[done]}/{task.fields[spawned]} done, {task.fields[rate]:.1f}/min"),
        TimeElapsedColumn(), console=err, transient=False,
    ) as progress:
        bar = progress.add_task("run", total=args.duration, scene=args.scene, done=0, spawned=0, rate=0.0)

        def on_progress(p) -> None:
            rate = p.parts_completed / (p.sim_time_s / 60) if p.sim_time_s > 0 else 0.0
            progress.update(bar, completed=p.sim_time_s, done=p.parts_completed, spawned=p.parts_spawned, rate=rate)

        with Launcher(options, on_progress, on_message=lambda text: progress.console.print(text, markup=False, highlight=False)) as launcher:
            progress.console.print(f"bus: {launcher.endpoint} (watch it: fleet monitor --connect {launcher.endpoint} --run {args.run_id})", markup=False, highlight=False)
            summary = launcher.run()
            if args.keep_logs:
                err.print(f"logs and reports kept in {launcher.dir}")
        progress.update(bar, completed=summary["sim_seconds"], done=summary["parts_completed"], spawned=summary["parts_spawned"])
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


def output_folder(flag: str, path: str, parents: bool = True) -> Path:
    """A folder to write results into, made if missing (with its parents, or refused when `parents` is False
    and the parent is missing); refused in one line when the path is a file."""
    folder = Path(path)
    if folder.exists() and not folder.is_dir():
        raise UsageError(f"{flag} {path}: exists and is not a folder")
    if not parents and not folder.parent.is_dir():
        raise UsageError(f"{flag} {path}: no folder {folder.parent}")
    folder.mkdir(parents=parents, exist_ok=True)
    return folder


def writable_file(flag: str, path: str) -> Path:
    """A file path whose folder exists (refused in one line otherwise)."""
    target = Path(path)
    if target.is_dir():
        raise UsageError(f"{flag} {path}: is a directory; give a file name, e.g. run.mcap")
    if not target.parent.is_dir():
        raise UsageError(f"{flag} {path}: no folder {target.parent}")
    return target


def write_run_artefacts(summary: dict, out_dir: Path) -> None:
    """`fleet run --out DIR`: the summary, and the time series and plots made from the run's recording."""
    from fleet.record.mcap_file import Recording
    from fleet.record.report import series_from_recording, write_report

    (out_dir / "summary.json").write_text(json.dumps(summary, indent=1) + "\n")
    if (summary.get("recording") or {}).get("file"):
        written = write_report(series_from_recording(Recording(summary["recording"]["file"])), out_dir)
        err.print(f"artefacts in {out_dir}: summary.json, {Path(summary['recording']['file']).name}, {', '.join(p.name for p in written)}",
                  markup=False, highlight=False)
    else:
        err.print(f"the recorder wrote nothing: only summary.json in {out_dir}", markup=False, highlight=False)


def cmd_report(args: argparse.Namespace) -> int:
    from fleet.record.mcap_file import Recording
    from fleet.record.report import series_from_recording, write_report

    recording = Recording(args.file)
    out_dir = output_folder("--out", args.out)
    series = series_from_recording(recording)
    written = write_report(series, out_dir)
    if series.summary is not None:
        (out_dir / "summary.json").write_text(json.dumps(series.summary, indent=1) + "\n")
    out.print(f"{args.file}: {len(series.arm_rows)} arm states, {len(series.line_rows)} line samples over {series.end_s:.1f} sim s")
    out.print(f"wrote {', '.join(p.name for p in written)} in {out_dir}")
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    import threading

    from fleet.bus.keys import Keys
    from fleet.bus.session import BusEndpoints, open_listening_session, open_session
    from fleet.processes import StopFlag
    from fleet.record.mcap_file import Recording
    from fleet.record.replay import Player

    recording = Recording(args.file)
    if not (math.isfinite(args.speed) and 0.01 <= args.speed <= 100):
        raise UsageError(f"--speed {args.speed:g}: give a factor from 0.01 to 100")
    try:
        keys = Keys(args.run_id or recording.run_id)
    except ValueError as exc:
        raise UsageError(f"--run-id: {exc}") from None
    stop = StopFlag(watch_parent=False)
    endpoints = BusEndpoints.from_args(args)
    if endpoints.listen or endpoints.config_file:
        session_cm, endpoint = open_session(endpoints), ", ".join(endpoints.listen) or "(from the Zenoh config)"
    else:
        session, endpoint = open_listening_session(endpoints)
        session_cm = contextlib.closing(session)
    with session_cm as session, Player(recording, session, keys, args.from_s, args.speed) as player:
        clock = player.clock
        err.print(f"replaying {args.file}: {clock.start_s:.1f} to {clock.end_s:.1f} sim s of run {recording.run_id!r} as run {keys.run!r} "
                  f"on {endpoint} (watch it: fleet monitor --connect {endpoint} --run-id {keys.run})", markup=False, highlight=False)
        if not args.monitor:
            player.run(stop, until_end=True)
            out.print(f"published {player.published} messages up to {clock.position_s:.1f} sim s" + (f" (stopped: {stop.reason})" if stop.reason else ""))
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


def cmd_sweep(args: argparse.Namespace) -> int:
    from fleet.sweep.grid import GridError, Override, grid, parse_seeds, scenes_for
    from fleet.sweep.results import write_results
    from fleet.sweep.runner import finished, load_results, run_local, run_ray

    if not (math.isfinite(args.duration) and 0 < args.duration <= 24 * 3600):
        raise UsageError(f"--duration {args.duration:g}: give a positive number of sim seconds (at most a day)")
    jobs = args.jobs or os.cpu_count() or 1
    if args.ray and importlib.util.find_spec("ray") is None:
        raise UsageError("--ray needs Ray: pip install 'clawfleet[rl]' (or pip install ray)")
    if jobs < 1:
        raise UsageError(f"--jobs {args.jobs}: at least 1")
    try:
        overrides = [Override.parse(t) for t in args.set or ()] + [
            Override(f"network.{field}", tuple(values)) for field, values in
            (("latency_ms", args.latency_ms), ("jitter_ms", args.jitter_ms), ("loss", args.loss)) if values
        ]
        cells = grid(args.scene, parse_seeds(args.seeds), args.allocator, args.duration, args.arms, overrides)
    except GridError as exc:
        raise UsageError(str(exc)) from None
    load_scene(args.scene, arms=args.arms)  # a bad scene: one line, before anything runs
    out_dir = output_folder("--out", args.out)
    scenes = scenes_for(cells, out_dir / "scenes")  # a bad --set: one line, before anything runs
    done = finished(out_dir, cells)
    todo = [c for c in cells if c.run_id not in done]
    err.print(f"sweep: {len(cells)} runs ({len(done)} already in {out_dir}), {len(todo)} to go, "
              f"{f'on the Ray cluster at {args.ray}' if args.ray else f'{jobs} at a time'}", markup=False, highlight=False)
    with Progress(TextColumn("sweep"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[last]}"), TimeElapsedColumn(),
                  console=err, transient=False) as progress:
        bar = progress.add_task("runs", total=len(cells), completed=len(done), last="")

        def on_done(cell, summary) -> None:
            progress.update(bar, advance=1, last=f"seed {cell.seed} {cell.allocator}: {summary.get('throughput_per_min', 0):.2f}/min ({summary.get('status')})")

        if todo and args.ray:
            run_ray(todo, out_dir, args.ray, on_done, scenes)
        elif todo:
            run_local(todo, out_dir, jobs, on_done, scenes)
    cells_rows, written = write_results(load_results(out_dir), out_dir)
    table = Table("allocator / overrides", "runs", "throughput /min (95% CI)", "completed", "missed", "bound fraction", "of the run's arrivals", "contacts")
    from fleet.sweep.results import label

    def ci(c, figure, digits=2):
        mean, half = c[f"{figure}_mean"], c[f"{figure}_ci95"]
        return "-" if mean != mean else (f"{mean:.{digits}f}" + ("" if half != half else f" ± {half:.{digits}f}"))

    for c in cells_rows:
        table.add_row(label(c), str(c["runs"]), ci(c, "throughput_per_min"), ci(c, "parts_completed", 1), ci(c, "parts_missed", 1),
                      ci(c, "bound_fraction"), ci(c, "run_bound_fraction"), ci(c, "inter_arm_contacts", 1))
    out.print(table)
    out.print(f"wrote {', '.join(p.name for p in written)} in {out_dir}")
    return 0


def cmd_record(args: argparse.Namespace) -> int:
    from fleet.nodes import recorder_node

    if not (args.connect or args.zenoh_config):
        raise UsageError("fleet record needs --connect ENDPOINT (fleet run prints its bus endpoint) or --zenoh-config FILE")
    writable_file("file", args.file)
    argv = ["--run", args.run_id, "--out", args.file, "--scene-timeout", str(args.wait), "--nice", "0"]
    for ep in args.connect or ():
        argv += ["--connect", ep]
    if args.zenoh_config:
        argv += ["--zenoh-config", args.zenoh_config]
    return recorder_node.main(argv)


def cmd_monitor(args: argparse.Namespace) -> int:
    from fleet.nodes import monitor_node

    if not (args.connect or args.zenoh_config):
        raise SystemExit("fleet: error: fleet monitor needs --connect ENDPOINT (fleet run prints its bus endpoint; or start it with --listen) "
                         "or --zenoh-config FILE")
    argv = ["--run", args.run_id, "--host", args.host, "--port", str(args.port), "--scene-timeout", str(args.wait)]
    for ep in args.connect or ():
        argv += ["--connect", ep]
    if args.zenoh_config:
        argv += ["--zenoh-config", args.zenoh_config]
    return monitor_node.main(argv)


def print_run_summary(s: dict) -> None:
    table = Table("figure", "value", title=f"{s['scene']}: {s['arms']} arms, {s['mode']}, seed {s['seed']} ({s['status']})")
    rows = [
        ("sim / wall seconds", f"{s['sim_seconds']:.1f} / {s['wall_seconds']:.1f}"),
        ("parts spawned / completed", f"{s['parts_spawned']} / {s['parts_completed']}"),
        ("missed / failed / on the line", f"{s['parts_missed']} / {s['parts_failed']} / {s['parts_in_progress']}"),
        ("throughput (per sim minute)", f"{s['throughput_per_min']:.2f}"),
        ("capacity bound (per minute)", "-" if s.get("throughput_bound_per_min") is None else
         f"{s['throughput_bound_per_min']:.2f}: {s['bound_fraction']:.0%} of it achieved, limited by {s['bottleneck']['name']}"),
        ("bound of this run's arrivals (per minute)", "-" if not s.get("run_bound_per_min") else
         f"{s['run_bound_per_min']:.2f}: {s['run_bound_fraction']:.0%} of it achieved; "
         f"{s['parts_completed']} of {s['parts_finishable']} parts that arrived in time to be finished"),
        ("arms: working / waiting for a grant (+ held at a fixture) / idle", "; ".join(
            f"{a} {t['working']:.0%} / {t['waiting_for_grant']:.0%}{f' (+{held:.0%})' if (held := t.get('held_at_fixture', 0)) else ''} / {t['idle']:.0%}"
            for a, t in s.get("arm_time", {}).items()) or "-"),
        ("inter-arm contacts (ticks)", str(s["inter_arm_contacts"])),
        ("min separation (m)", "-" if s["min_separation_m"] is None else f"{s['min_separation_m']:.3f}"),
        ("grants denied", str(s["grants_denied"])),
        ("round trip p50 / p99 (ms)", f"{s['latency_p50_ms']} / {s['latency_p99_ms']}"),
        ("dropped messages", str(s["dropped_messages"])),
        ("arms lost / respawns", f"{', '.join(s['arms_lost']) or 'none'} / {s['respawns']}"),
    ]
    for row in rows:
        table.add_row(*row)
    out.print(table)


def print_bench(table: Table, rows: list, as_json: bool) -> int:
    """A benchmark's table, and with `--json` its rows as one JSON line (the last on stdout)."""
    out.print(table)
    if as_json:
        print(json.dumps([r.__dict__ for r in rows]))
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from fleet.bench_physics import bench_physics

    table = Table("arms", "parts on belt", "physics steps/s", "sim s per wall s")
    rows = []
    for n in args.arms:
        row = bench_physics(n, args.seconds)
        rows.append(row)
        table.add_row(str(n), str(row.parts_active), f"{row.steps_per_s:,.0f}", f"{row.sim_s_per_wall_s:.1f}")
    out.print(table)
    if args.json:
        print(json.dumps([{"arms": r.arms, "steps_per_s": round(r.steps_per_s, 1)} for r in rows]))
    return 0


def cmd_bench_bus(args: argparse.Namespace) -> int:
    from fleet.bench_runtime import bench_bus

    table = Table("arms", "ticks", "round trip p50 (ms)", "p99 (ms)", "lockstep ticks/s", "msgs/arm/sim s", "protocol 1", "fewer")
    rows = []
    for n in args.arms:
        row = bench_bus(n, args.ticks)
        rows.append(row)
        table.add_row(str(n), str(row.ticks), f"{row.p50_ms:.2f}", f"{row.p99_ms:.2f}", f"{row.ticks_per_s:,.0f}",
                      f"{row.messages_per_arm_per_s:.1f}", f"{row.messages_per_arm_per_s_v1:.0f}",
                      f"{row.messages_per_arm_per_s_v1 / row.messages_per_arm_per_s:.1f}x")
    return print_bench(table, rows, args.json)


def cmd_bench_run(args: argparse.Namespace) -> int:
    from fleet.bench_runtime import bench_run

    table = Table("arms", "sim s", "wall s", "sim s per wall s", "wall / raw physics (still)", "wall / replay (same motion)",
                  "parts done", "contacts", "bus msgs/arm/s", "p99 (ms)")
    rows = []
    for n in args.arms:
        row = bench_run(n, args.seconds, args.repeats)
        rows.append(row)
        table.add_row(
            str(n), f"{row.sim_seconds:.0f}", f"{row.wall_seconds:.1f}", f"{row.realtime_factor:.2f}",
            f"{row.ratio_to_physics:.2f}", f"{row.ratio_to_replay:.2f}", str(row.parts_completed), str(row.contacts),
            f"{row.messages_per_arm_per_s:.0f}", f"{row.p99_ms}",
        )
    out.print(table)
    if args.json:
        print(json.dumps([r.__dict__ | {"realtime_factor": r.realtime_factor, "ratio_to_physics": r.ratio_to_physics,
                                        "ratio_to_replay": r.ratio_to_replay} for r in rows]))
    return 0


def cmd_bench_monitor(args: argparse.Namespace) -> int:
    from fleet.bench_runtime import bench_monitor

    rows = bench_monitor(args.scene, args.arms, args.seconds, args.repeats, browser=not args.no_browser)
    table = Table("variant", "sim loop wall s (median)", "ratio to no monitor", "monitor frames/s")
    for r in rows:
        table.add_row(r.variant, f"{r.loop_wall_seconds:.2f}", f"{r.ratio_to_plain:.3f}", "-" if r.monitor_frames_per_s is None else f"{r.monitor_frames_per_s:.1f}")
    return print_bench(table, rows, args.json)


def cmd_bench_record(args: argparse.Namespace) -> int:
    from fleet.bench_runtime import bench_record

    rows = bench_record(args.scene, args.arms, args.seconds, args.repeats)
    table = Table("variant", "sim loop wall s", "run wall s", "whole run wall s", "loop ratio", "run ratio", "whole run ratio", "MB / sim minute",
                  "messages / sim s")
    for r in rows:
        table.add_row(r.variant, f"{r.loop_wall_seconds:.2f}", f"{r.run_wall_seconds:.2f}", f"{r.whole_wall_seconds:.2f}", f"{r.loop_ratio:.3f}",
                      f"{r.run_ratio:.3f}", f"{r.whole_ratio:.3f}",
                      "-" if r.mb_per_sim_minute is None else f"{r.mb_per_sim_minute:.2f}", "-" if r.messages_per_sim_s is None else f"{r.messages_per_sim_s:.0f}")
    return print_bench(table, rows, args.json)


def cmd_bench_collision(args: argparse.Namespace) -> int:
    from coordinator.bench import bench_collision

    table = Table("arms", "full-cell separation (ms)", "with every arm moved (ms)", "grant check, 2 s path (ms)", "samples")
    rows = [bench_collision(n) for n in args.arms]
    for r in rows:
        table.add_row(str(r.arms), f"{r.separation_ms:.3f}", f"{r.place_and_separation_ms:.3f}", f"{r.grant_ms:.2f}", str(r.grant_samples))
    return print_bench(table, rows, args.json)


def cmd_bench_allocation(args: argparse.Namespace) -> int:
    from coordinator.bench import bench_allocation

    table = Table("pending tasks", "arms", "optimal assignment (ms)")
    rows = [bench_allocation(n, args.arms) for n in args.tasks]
    for r in rows:
        table.add_row(str(r.tasks), str(r.arms), f"{r.solve_ms:.3f}")
    return print_bench(table, rows, args.json)


def cmd_bench_lines(args: argparse.Namespace) -> int:
    from fleet.bench_runtime import bench_lines

    cases = [(c.split(":")[0], int(c.split(":")[1]) if ":" in c else None) for c in args.cases]
    table = Table("scene", "arms", "allocator", "throughput (/min)", "completed / spawned", "bound fraction (of the run's own)",
                  "contacts", "min separation (m)", "grants given / denied")
    rows = bench_lines(cases, args.allocators, args.seconds, args.seed)
    for r in rows:
        sep = "-" if r.min_separation_m is None else f"{r.min_separation_m:.3f}"
        fraction = "-" if r.bound_fraction is None else f"{r.bound_fraction:.2f} ({'-' if r.run_bound_fraction is None else f'{r.run_bound_fraction:.2f}'})"
        table.add_row(r.scene, str(r.arms), r.allocator, f"{r.throughput_per_min:.2f}", f"{r.parts_completed} / {r.parts_spawned}", fraction,
                      str(r.contacts), sep, f"{r.grants_given} / {r.grants_denied}")
    return print_bench(table, rows, args.json)


def cmd_bench_env(args: argparse.Namespace) -> int:
    from fleet.env.bench import bench_env, bench_robosuite, bench_vector

    if args.vector:
        table = Table("cells", "worker processes", "arms per cell", "task", "agent-steps/s", "against 1 cell in process")
        rows = [bench_vector(1, 0, args.arms[0], args.tasks[0], args.steps)]
        rows += [bench_vector(n, min(n, os.cpu_count() or 1), args.arms[0], args.tasks[0], args.steps) for n in args.vector]
        for r in rows:
            table.add_row(str(r.cells), str(r.cpus), str(r.arms), r.task, f"{r.agent_steps_per_s:,.0f}",
                          f"{r.agent_steps_per_s / rows[0].agent_steps_per_s:.2f}x")
        return print_bench(table, rows, args.json)

    baseline = [bench_robosuite(args.robosuite, args.steps)] if args.robosuite else []  # before and after: drift hits both
    rows = [bench_env(n, task, args.steps, distributed=args.distributed) for task in args.tasks for n in args.arms]
    baseline += [bench_robosuite(args.robosuite, args.steps)] if args.robosuite else []
    robosuite_rate = sum(b.agent_steps_per_s for b in baseline) / len(baseline) if baseline else None
    table = Table("arms", "task", "agent-steps/s", "env steps/s", "env time / raw physics", *(["against robosuite"] if baseline else []))
    for r in rows:
        table.add_row(str(r.arms), r.task, f"{r.agent_steps_per_s:,.0f}", f"{r.steps / r.env_s:,.0f}", f"{r.ratio_to_physics:.2f}",
                      *([f"{r.agent_steps_per_s / robosuite_rate:.1f}x"] if baseline else []))
    out.print(table)
    if baseline:
        b = baseline[0]
        out.print(f"robosuite {b.robosuite} {b.task} ({b.arms} Pandas, MuJoCo {b.mujoco}): "
                  + ", ".join(f"{x.agent_steps_per_s:,.0f}" for x in baseline) + " agent-steps/s (before, after)")
    if args.json:
        env_rows = [r.__dict__ | {"agent_steps_per_s": r.agent_steps_per_s, "ratio_to_physics": r.ratio_to_physics} for r in rows]
        print(json.dumps(env_rows if not baseline else {"env": env_rows, "robosuite": [b.__dict__ for b in baseline]}))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="fleet", description="clawfleet: several claw arms sharing one assembly line")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("run", help="run the line: sim server, coordinator and one controller per arm as processes")
    p.add_argument("scene", nargs="?", default="assembly_line", help="bundled scene name or scene file (default assembly_line)")
    p.add_argument("--arms", type=int, default=None, help="arm count for scenes with an arm row")
    p.add_argument("--duration", type=float, default=120.0, help="sim seconds to run (default 120)")
    p.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep")
    p.add_argument("--speed", type=float, default=1.0, help="realtime: speed factor against the wall clock")
    p.add_argument("--seed", type=int, default=None, help="overrides the scene's seed")
    p.add_argument("--respawn", action="store_true", help="restart a controller or the coordinator that dies (a new coordinator takes over the line)")
    p.add_argument("--allocator", choices=("optimal", "auction", "greedy"), default="optimal", help="how tasks go to arms (default optimal)")
    p.add_argument("--no-pipeline", dest="pipeline", action="store_false",
                   help="give a fixture's next part to an arm only once the fixture is ready for it (default: before, the arm held at the edge)")
    p.add_argument("--rt", action="store_true", help="controllers ask for real-time scheduling")
    p.add_argument("--run-id", default="line", help="keeps several lines on one Zenoh network apart")
    p.add_argument("--summary", metavar="FILE", help="also write the summary JSON here")
    p.add_argument("--keep-logs", action="store_true", help="keep each process's log and report (the path is printed)")
    p.add_argument("--json", action="store_true", help="last stdout line: the summary as one JSON object")
    p.add_argument("--monitor", action="store_true", help="serve the browser monitor (Viser) of this run; see --host/--port")
    p.add_argument("--record", metavar="FILE.mcap", help="record every bus message, TF, joint states and markers (rosbag2-layout MCAP)")
    p.add_argument("--out", metavar="DIR", help="write the run's artefacts here: summary.json, recording.mcap, time series CSV, plots")
    p.add_argument("--bus-config", metavar="DIR", help="the line's bus from `fleet bus-config`: the sim a router, every node logged in "
                   "with its own config (TLS, passwords, access control)")
    p.add_argument("--hosts", metavar="FILE", help="the network namespace each node starts in (YAML `nodes: {sim: NS, ...}`; needs --bus-config)")
    add_monitor_arguments(p)
    add_fault_arguments(p)
    add_bus_arguments(p)
    p.set_defaults(func=cmd_run)

    p = sub.add_parser("bus-config", help="write one Zenoh config per node for a line across hosts: the sim a router with TLS, logins and access control")
    p.add_argument("--address", required=True, help="the IP address of the sim's host, as the other hosts reach it")
    p.add_argument("--port", type=int, default=7447, help="the port the sim's router listens on (default 7447)")
    p.add_argument("--scene", default="assembly_line", help="the scene whose arms get a login each (default assembly_line)")
    p.add_argument("--arms", type=int, default=None, help="arm count for scenes with an arm row")
    p.add_argument("--insecure", action="store_true", help="plain TCP: no TLS, no logins, no access control (a trusted network only)")
    p.add_argument("--out", metavar="DIR", required=True, help="where to write the configs (keys and passwords readable by you only)")
    p.set_defaults(func=cmd_bus_config)

    p = sub.add_parser("record", help="record a running line to an MCAP file (attaches over the bus; Ctrl-C finishes the file)")
    p.add_argument("file", help="the MCAP file to write")
    p.add_argument("--run-id", default="line", help="run id of the line (default line)")
    p.add_argument("--wait", type=float, default=15.0, help="seconds to wait for the line's sim to answer (default 15)")
    add_bus_arguments(p)
    p.set_defaults(func=cmd_record)

    p = sub.add_parser("sweep", help="a grid of runs over seeds, allocators and scene overrides, in parallel (or on Ray), resumable")
    p.add_argument("scene", help="bundled scene name or scene file")
    p.add_argument("--seeds", default="0-4", help="a range (0-19) or a list (1,4,9); default 0-4")
    p.add_argument("--allocator", nargs="+", default=["optimal"], choices=("optimal", "auction", "greedy"))
    p.add_argument("--set", action="append", metavar="FIELD.PATH=V1,V2", help="a scene field and the values it takes (repeatable), e.g. conveyor.speed_m_per_s=0.05,0.1")
    p.add_argument("--arms", type=int, default=None, help="arm count for scenes with an arm row")
    p.add_argument("--duration", type=float, default=60.0, help="sim seconds per run (default 60)")
    p.add_argument("--latency-ms", type=float, nargs="+", metavar="MS", help="bus latency levels, each way on every link (network.latency_ms)")
    p.add_argument("--jitter-ms", type=float, nargs="+", metavar="MS", help="bus jitter levels (network.jitter_ms)")
    p.add_argument("--loss", type=float, nargs="+", metavar="P", help="bus loss levels (network.loss)")
    p.add_argument("--jobs", type=int, default=None, help="runs at a time on this machine (default: its cores)")
    p.add_argument("--ray", metavar="ADDRESS", help="run each run as a Ray task on the Ray cluster at ADDRESS (e.g. 127.0.0.1:6379; docs/running.md)")
    p.add_argument("--out", required=True, metavar="DIR", help="results: runs/*.json, runs.csv, cells.csv, plots; a run already there is not run again")
    p.set_defaults(func=cmd_sweep)

    p = sub.add_parser("replay", help="play a recording back onto the bus; with --monitor, in the browser with a time slider")
    p.add_argument("file", help="an MCAP file written by fleet run --record / fleet record")
    p.add_argument("--monitor", action="store_true", help="serve the browser monitor with play, pause, scrub and speed (Ctrl-C ends)")
    p.add_argument("--speed", type=float, default=1.0, help="sim seconds per wall second (default 1)")
    p.add_argument("--from", dest="from_s", type=float, default=None, metavar="S", help="start at this sim time")
    p.add_argument("--run-id", default=None, help="publish as this run id (default: the recorded one)")
    add_monitor_arguments(p)
    add_bus_arguments(p)
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("report", help="time series (CSV) and plots (Gantt, throughput, separation, round trips) from a recording")
    p.add_argument("file", help="an MCAP file written by fleet run --record / fleet record")
    p.add_argument("--out", required=True, metavar="DIR", help="folder for the CSVs and PNGs")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("monitor", help="watch and control a running line in the browser (attaches over the bus)")
    p.add_argument("--run-id", default="line", help="run id of the line (default line)")
    p.add_argument("--wait", type=float, default=15.0, help="seconds to wait for the line's sim to answer (default 15)")
    add_monitor_arguments(p)
    add_bus_arguments(p)
    p.set_defaults(func=cmd_monitor)

    p = sub.add_parser("check", help="validate a scene file: prints ok, or one line naming file, field and reason")
    p.add_argument("file", help="scene file path or bundled scene name")
    p.add_argument("--arms", type=int, default=None, help="arm count for scenes with an arm row")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("scenes", help="list the bundled scenes")
    p.set_defaults(func=cmd_scenes)

    p = sub.add_parser("robots", help="list the registered robot models, or check one (--check)")
    p.add_argument("--check", metavar="ROBOT", default=None,
                   help="a robot uid or robot YAML file: kinematics against the physics, home, gripper, pick trials")
    p.add_argument("--trials", type=int, default=3, help="pick trials with --check (0: none)")
    p.add_argument("--seed", type=int, default=0, help="first trial seed with --check")
    p.set_defaults(func=cmd_robots)

    p = sub.add_parser("trials", help="seeded pick-and-place trials: conveyor to bin, friction grasps")
    p.add_argument("--robot", default="openclaw", help="a robot uid or robot YAML file")
    p.add_argument("--trials", type=int, default=50)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--physics-hz", type=float, default=None, help="physics rate to try (a whole multiple of the 100 Hz servo rate)")
    p.add_argument("--solver-iterations", type=int, default=None, help="PhysX position iterations to try (the scene's: 20)")
    p.add_argument("--json", action="store_true", help="last stdout line: one JSON object")
    p.set_defaults(func=cmd_trials)

    p = sub.add_parser("tune", help="seeded search over a robot's drive gains and pick timing, judged by pick trials")
    p.add_argument("--robot", default="openclaw", help="a robot uid or robot YAML file")
    p.add_argument("--candidates", type=int, default=12, help="settings tried: the registered one and draws from the search space")
    p.add_argument("--trials", type=int, default=20, help="seeded pick trials per setting")
    p.add_argument("--seed", type=int, default=0, help="seed of the draws and first trial seed")
    p.add_argument("--json", action="store_true", help="last stdout line: one JSON object")
    p.set_defaults(func=cmd_tune)

    p = sub.add_parser("bench", help="benchmarks")
    bench = p.add_subparsers(dest="bench", required=True)
    b = bench.add_parser("physics", help="raw physics steps/s of the sorting line (no controllers)")
    b.add_argument("--arms", type=int, nargs="+", default=[1, 2, 4, 8])
    b.add_argument("--seconds", type=float, default=4.0, help="sim seconds timed per row")
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench)
    b = bench.add_parser("bus", help="lockstep state-to-command round trip over Zenoh, idle controller processes")
    b.add_argument("--arms", type=int, nargs="+", default=[1, 2, 4, 8])
    b.add_argument("--ticks", type=int, default=1500)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_bus)
    b = bench.add_parser("run", help="whole lockstep lines (all processes) against raw physics of the same scene")
    b.add_argument("--arms", type=int, nargs="+", default=[1, 2, 4, 8])
    b.add_argument("--seconds", type=float, default=60.0, help="sim seconds per run")
    b.add_argument("--repeats", type=int, default=3, help="runs per arm count (medians)")
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_run)
    b = bench.add_parser("monitor", help="lockstep runs without and with the browser monitor: what watching costs")
    b.add_argument("--scene", default="sorting_line")
    b.add_argument("--arms", type=int, default=4)
    b.add_argument("--seconds", type=float, default=30.0, help="sim seconds per run")
    b.add_argument("--repeats", type=int, default=3)
    b.add_argument("--no-browser", action="store_true", help="skip the variant with a headless chromium on the page")
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_monitor)
    b = bench.add_parser("record", help="lockstep runs without and with --record: what recording costs, MB per sim minute")
    b.add_argument("--scene", default="assembly_line")
    b.add_argument("--arms", type=int, default=None)
    b.add_argument("--seconds", type=float, default=60.0, help="sim seconds per run")
    b.add_argument("--repeats", type=int, default=3)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_record)
    b = bench.add_parser("collision", help="FCL guard: full-cell separation and one grant check")
    b.add_argument("--arms", type=int, nargs="+", default=[2, 4, 8])
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_collision)
    b = bench.add_parser("allocation", help="optimal assignment for many pending tasks")
    b.add_argument("--tasks", type=int, nargs="+", default=[10, 100, 1000])
    b.add_argument("--arms", type=int, default=8)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_allocation)
    b = bench.add_parser("lines", help="throughput, contacts and separation of whole runs per scene and allocator")
    b.add_argument("--cases", nargs="+", default=["assembly_line", "handover", "mixed_infeed", "pick_cell", "sorting_line:2", "sorting_line:4", "sorting_line:6"],
                   help="SCENE or SCENE:ARMS")
    b.add_argument("--allocators", nargs="+", default=["optimal", "auction", "greedy"], choices=("optimal", "auction", "greedy"))
    b.add_argument("--seconds", type=float, default=120.0, help="sim seconds per run")
    b.add_argument("--seed", type=int, default=0)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_lines)
    b = bench.add_parser("env", help="PettingZoo env: agent-steps/s and env time against raw physics")
    b.add_argument("--arms", type=int, nargs="+", default=[2, 4, 8])
    b.add_argument("--tasks", nargs="+", choices=("reach", "pick_place", "line"), default=["reach", "line"])
    b.add_argument("--steps", type=int, default=400)
    b.add_argument("--distributed", action="store_true", help="actions through Zenoh to one process per arm")
    b.add_argument("--vector", type=int, nargs="+", metavar="N", help="N cells at once in worker processes (SuperSuit), against one in process")
    b.add_argument("--robosuite", metavar="PYTHON", help="also time robosuite's TwoArmLift with this interpreter (one that has robosuite; "
                   "docs/benchmarks.md says how to make one) before and after, and give each row's agent-steps/s against it")
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_env)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except user_errors() as exc:
        print(f"fleet: error: {exc}", file=sys.stderr)
        return 2
    except RuntimeError as exc:  # a run that could not start (the launcher's RunError), a failed benchmark
        print(f"fleet: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("fleet: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
