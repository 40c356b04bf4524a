"""`fleet sweep`: a grid of runs over seeds, allocators and scene overrides."""

from __future__ import annotations

import argparse
import importlib.util
import math
import os
from pathlib import Path

from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
)
from rich.table import Table

from fleet.cli.allocators import allocator_spec
from fleet.cli.errors import (
    UsageError,
    err,
    out,
    output_folder,
    positive_numbers,
)
from fleet.cli.run import check_camera_flags
from fleet.common.scene_loading import load_checked_scene


def sweep_jobs(args: argparse.Namespace) -> int:
    """Runs at a time, once the flags that cannot work are refused in one line."""
    if args.duration is None:
        args.duration = None if args.from_snapshot else DEFAULT_DURATION_S
    if args.duration is not None and not (math.isfinite(args.duration) and 0 < args.duration <= 24 * 3600):
        raise UsageError(f"--duration {args.duration:g}: give a positive number of sim seconds (at most a day)")
    jobs = args.jobs or os.cpu_count() or 1
    if args.ray and importlib.util.find_spec("ray") is None:
        raise UsageError("--ray needs Ray: pip install 'clawfleet[rl]' (or pip install ray)")
    if jobs < 1:
        raise UsageError(f"--jobs {args.jobs}: at least 1")
    return jobs


DEFAULT_DURATION_S = 60.0


def branch_scene(args: argparse.Namespace) -> str:
    """`--from SNAPSHOT`: the snapshot's scene (its name, for the results), once the flags a branch cannot take are
    refused in one line; without `--from`, the scene given."""
    if not args.from_snapshot:
        if not args.scene:
            raise UsageError("give a scene (bundled name or file), or --from SNAPSHOT")
        return args.scene
    from fleet.snapshot.snapshot_file import SnapshotError, read_snapshot

    try:
        snapshot = read_snapshot(args.from_snapshot)
    except SnapshotError as exc:
        raise UsageError(str(exc)) from None
    if args.scene and args.scene not in (snapshot.scene_name, snapshot.scene.file_name):
        raise UsageError(f"{args.from_snapshot} is a snapshot of {snapshot.scene_name}, not of {args.scene}")
    given = {
        "--load": args.load,
        "--arms": args.arms,
        "--latency-ms": args.latency_ms,
        "--jitter-ms": args.jitter_ms,
        "--loss": args.loss,
        "--ray": args.ray,
    }
    refused = [flag for flag, value in given.items() if value]
    if refused:
        raise UsageError(
            f"a branch from a snapshot compares allocators over seeds on this machine: leave out {', '.join(refused)}"
        )
    from fleet.run.restore import check_restore_overrides
    from fleet.sweep.grid import GridError, Override

    try:
        check_restore_overrides({Override.parse(t).path: None for t in args.set or ()})
    except (SnapshotError, GridError) as exc:
        raise UsageError(str(exc)) from None
    args.from_snapshot = str(Path(args.from_snapshot).resolve())
    return snapshot.scene_name


def load_list(text: str) -> list[float]:
    """`--load`'s value: positive numbers separated by commas (argparse's `type`)."""
    return positive_numbers(text, "positive multiples of capacity, e.g. 0.5,1.0,1.5")


def sweep_overrides(args: argparse.Namespace) -> list:
    """The grid's overrides: `--set`, the network levels, the offered loads."""
    from fleet.common.scene_overrides import LOAD
    from fleet.sweep.grid import Override

    network = (("latency_ms", args.latency_ms), ("jitter_ms", args.jitter_ms), ("loss", args.loss))
    return (
        [Override.parse(t) for t in args.set or ()]
        + [Override(f"network.{field}", tuple(values)) for field, values in network if values]
        + ([Override(LOAD, tuple(args.load))] if args.load else [])
    )


def sweep_cells(args: argparse.Namespace) -> tuple[list, dict[str, str], Path]:
    """The sweep's runs, the scene each runs (a branch: the snapshot) and its output folder; a flag, scene or
    override that cannot work refused in one line before anything runs."""
    from fleet.sweep.grid import GridError, grid, parse_seeds, scenes_for

    scene = branch_scene(args)
    args.allocator = [allocator_spec(spec) for spec in args.allocator]
    try:
        seeds = parse_seeds(args.seeds)
        overrides = sweep_overrides(args)
        perceptions = list(dict.fromkeys(args.perception))
        grid_args = (args.duration, args.arms, overrides, args.from_snapshot, perceptions)
        cells = grid(scene, seeds, args.allocator, *grid_args)
    except GridError as exc:
        raise UsageError(str(exc)) from None
    if args.from_snapshot:  # a branch runs the snapshot's scene
        if "cameras" in perceptions:
            raise UsageError("--perception cameras: a line working from its cameras cannot be restored yet")
        return cells, {c.run_id: args.from_snapshot for c in cells}, output_folder("--out", args.out)
    checked = load_checked_scene(scene, arms=args.arms)
    if "cameras" in perceptions:
        check_camera_flags(argparse.Namespace(perception="cameras", cameras=None), checked)
    out_dir = output_folder("--out", args.out)
    return cells, scenes_for(cells, out_dir / "scenes"), out_dir


def cmd_sweep(args: argparse.Namespace) -> int:
    from fleet.sweep.results import write_results
    from fleet.sweep.runner import finished, load_results, run_local, run_ray

    jobs = sweep_jobs(args)
    cells, scenes, out_dir = sweep_cells(args)
    done = finished(out_dir, cells)
    todo = [c for c in cells if c.run_id not in done]
    err.print(
        f"sweep: {len(cells)} runs ({len(done)} already in {out_dir}), {len(todo)} to go, "
        f"{f'on the Ray cluster at {args.ray}' if args.ray else f'{jobs} at a time'}",
        markup=False,
        highlight=False,
    )
    with Progress(
        TextColumn("sweep"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[last]}"),
        TimeElapsedColumn(),
        console=err,
        transient=False,
    ) as progress:
        bar = progress.add_task("runs", total=len(cells), completed=len(done), last="")

        def on_done(cell, summary) -> None:
            progress.update(
                bar,
                advance=1,
                last=(
                    f"seed {cell.seed} {cell.allocator}: {summary.get('throughput_per_min', 0):.2f}/min "
                    f"({summary.get('status')})"
                ),
            )

        if todo and args.ray:
            run_ray(todo, out_dir, args.ray, on_done, scenes)
        elif todo:
            run_local(todo, out_dir, jobs, on_done, scenes)
    cells_rows, written = write_results(load_results(out_dir), out_dir)
    out.print(cells_table(cells_rows))
    out.print(f"wrote {', '.join(p.name for p in written)} in {out_dir}")
    return 0


def cells_table(cells_rows: list[dict]) -> Table:
    """The sweep's cells: means and 95% intervals of each allocator and override."""
    from fleet.sweep.results import label

    table = Table(
        "allocator / overrides",
        "runs",
        "throughput /min (95% CI)",
        "completed",
        "missed",
        "bound fraction",
        "of the run's arrivals",
        "contacts",
    )
    seeing = any(c.get("perception") == "cameras" for c in cells_rows)
    if seeing:  # what seeing cost: the p95 error of the parts seen and the grasps that held
        table.add_column("seen p95 mm")
        table.add_column("picks held")

    def ci(c, figure, digits=2):
        mean, half = c[f"{figure}_mean"], c[f"{figure}_ci95"]
        return "-" if mean != mean else (f"{mean:.{digits}f}" + ("" if half != half else f" ± {half:.{digits}f}"))

    for c in cells_rows:
        table.add_row(
            label(c),
            str(c["runs"]),
            ci(c, "throughput_per_min"),
            ci(c, "parts_completed", 1),
            ci(c, "parts_missed", 1),
            ci(c, "bound_fraction"),
            ci(c, "run_bound_fraction"),
            ci(c, "inter_arm_contacts", 1),
            *((ci(c, "seen_error_p95_mm", 1), ci(c, "pick_success")) if seeing else ()),
        )
    return table


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """This group's sub-commands."""
    p = sub.add_parser(
        "sweep", help="a grid of runs over seeds, allocators and scene overrides, in parallel (or on Ray), resumable"
    )
    p.add_argument("scene", nargs="?", help="bundled scene name or scene file (with --from: the snapshot's)")
    p.add_argument("--seeds", default="0-4", help="a range (0-19) or a list (1,4,9); default 0-4")
    p.add_argument(
        "--allocator",
        nargs="+",
        default=["optimal"],
        help="allocators to compare: built-ins (optimal, auction, greedy), installed plug-ins, package.module:Name, "
        "policy:FILE",
    )
    _add_grid_arguments(p)
    p.add_argument("--arms", type=int, default=None, help="arm count for scenes with an arm row")
    p.add_argument(
        "--perception",
        nargs="+",
        choices=("truth", "cameras"),
        default=["truth"],
        help="where the line's parts come from (`fleet run --perception`); both: each seed run either way, compared",
    )
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        help="sim seconds per run (default 60; with --from: from the snapshot on, default to where its run was to end)",
    )
    p.add_argument(
        "--from",
        dest="from_snapshot",
        metavar="SNAPSHOT",
        help="branch every run from this snapshot (`fleet run --snapshot-at`): each allocator from one identical "
        "state, each seed drawing its own arrivals from there on; paired intervals as for any sweep",
    )
    p.add_argument("--loss", type=float, nargs="+", metavar="P", help="bus loss levels (network.loss)")
    p.add_argument("--jobs", type=int, default=None, help="runs at a time on this machine (default: its cores)")
    p.add_argument(
        "--ray",
        metavar="ADDRESS",
        help="run each run as a Ray task on the Ray cluster at ADDRESS (e.g. 127.0.0.1:6379; docs/running.md)",
    )
    p.add_argument(
        "--out",
        required=True,
        metavar="DIR",
        help="results: runs/*.json, runs.csv, cells.csv, plots; a run already there is not run again",
    )
    p.set_defaults(func=cmd_sweep)


def _add_grid_arguments(p: argparse.ArgumentParser) -> None:
    """What a sweep varies besides seeds and allocators: scene fields, offered load, the bus's faults."""
    p.add_argument(
        "--set",
        action="append",
        metavar="FIELD.PATH=V1,V2",
        help="a scene field and the values it takes (repeatable), e.g. conveyor.speed_m_per_s=0.05,0.1",
    )
    p.add_argument(
        "--load",
        type=load_list,
        metavar="L1,L2",
        help="offered loads: every feeder scaled so parts arrive at these multiples of what the arms can just "
        "complete (1.0), e.g. 0.5,0.75,1.0,1.25,1.5; draws throughput, missed parts and utilisation against load",
    )
    p.add_argument(
        "--latency-ms",
        type=float,
        nargs="+",
        metavar="MS",
        help="bus latency levels, each way on every link (network.latency_ms)",
    )
    p.add_argument("--jitter-ms", type=float, nargs="+", metavar="MS", help="bus jitter levels (network.jitter_ms)")
