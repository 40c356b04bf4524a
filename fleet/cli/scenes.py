"""`fleet check`, `fleet scenes` and `fleet reach`: validate a scene and print its capacity bound; list the bundled
scenes; fill a scene's reach tables ahead of its runs."""

from __future__ import annotations

import argparse

from rich.markup import escape
from rich.table import Table

from fleet.cli.errors import (
    MissingModelsError,
    UnknownRobotError,
    UsageError,
    err,
    out,
)
from fleet.common.scene_loading import load_checked_scene
from scenes.loader import bundled_scene_names
from scenes.schema import Camera


def cmd_check(args: argparse.Namespace) -> int:
    from coordinator.capacity import capacity_bound

    scene = load_checked_scene(args.file, arms=args.arms)
    print("ok")
    print(capacity_line(capacity_bound(scene)))
    for camera in scene.cameras:
        print(camera_line(camera))
    return 0


def camera_line(camera: Camera) -> str:
    """One camera in one line: where it stands, its images and what they cost in pixels per second."""
    images = "+".join(camera.images)
    return (
        f"camera {camera.name}: {camera.mount}, {camera.width_px}x{camera.height_px} px, {camera.fov_deg:g} deg, "
        f"{camera.rate_hz:g} Hz, {images} ({camera.pixels_per_s:,.0f} px/s)"
    )


def capacity_line(bound) -> str:
    """The capacity bound in one line: what the line could complete at best, and what limits it."""
    text = f"capacity: at best {bound.throughput_bound_per_min:.2f} parts/min of {bound.arrivals_per_min:.2f} arriving"
    if bound.bottleneck == "arrivals":
        busiest = f"{bound.busiest or '-'} {bound.bottleneck_busy_fraction:.0%} of the time"
        text += f" (the line can take them all; busiest: {busiest})"
    else:
        text += f" (bottleneck: {bound.bottleneck}, busy all the time)"
    if bound.unservable:
        text += f"; no arm can serve {', '.join(bound.unservable)}"
    if bound.idle_arms:
        idle = ", ".join(bound.idle_arms)
        text += f"; {idle} can serve no hop (no part and its next station both in its reach): it will stand idle"
    return text


def cmd_scenes(args: argparse.Namespace) -> int:
    """Every bundled scene; one this install cannot run (a robot whose extra is missing) is listed, marked with
    what it needs."""
    table = Table("scene", "arms", "description")
    for name in bundled_scene_names():
        try:
            scene = load_checked_scene(name)
        except (MissingModelsError, UnknownRobotError) as exc:
            table.add_row(name, "-", f"[yellow]cannot run here: {escape(str(exc))}[/yellow]")
            continue
        table.add_row(name, str(len(scene.arms)), scene.description)
    out.print(table)
    return 0


def cmd_reach(args: argparse.Namespace) -> int:
    import os
    import time

    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from coordinator.reach_table import tables_dir
    from fleet.common.reach_fill import fill_tables, missing_cells

    if tables_dir() is None:
        raise UsageError("reach tables are off (CLAWFLEET_CACHE_DIR=off): nothing to fill")
    scene = load_checked_scene(args.file, arms=args.arms)
    jobs = args.jobs or os.cpu_count() or 1
    started = time.perf_counter()
    total = sum(len(cells) for _, cells, _ in missing_cells(scene).values())
    columns = (TextColumn("reach"), BarColumn(), MofNCompleteColumn(), TextColumn("cells"), TimeElapsedColumn())
    with Progress(*columns, console=err, disable=args.quiet) as progress:
        bar = progress.add_task("cells", total=total)
        fills = fill_tables(scene, jobs, lambda n: progress.advance(bar, n))
    table = Table("arm", "cells a run asks", "worked out now", "of those reached")
    for f in fills:
        table.add_row(f.arm, str(f.cells), str(f.missing), str(f.reached) if f.missing else "-")
    if not args.quiet:
        out.print(table)
    seconds = time.perf_counter() - started
    where = tables_dir()
    print(f"reach tables of {scene.name}: {total} cells worked out in {seconds:.1f} s on {jobs} processes; in {where}")
    return 0


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """This group's sub-commands."""
    p = sub.add_parser("check", help="validate a scene file: prints ok, or one line naming file, field and reason")
    p.add_argument("file", help="scene file path or bundled scene name")
    p.add_argument("--arms", type=int, default=None, help="arm count for scenes with an arm row")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("scenes", help="list the bundled scenes")
    p.set_defaults(func=cmd_scenes)

    p = sub.add_parser(
        "reach",
        help="work out every arm's reach over a scene's belt and stations ahead of its runs (kept on disk: "
        "no decision of a later run waits on IK for them)",
    )
    p.add_argument("file", help="scene file path or bundled scene name")
    p.add_argument("--arms", type=int, default=None, help="arm count for scenes with an arm row")
    p.add_argument("--jobs", type=int, default=None, help="processes to work in (default: every core)")
    p.add_argument("--quiet", action="store_true", help="no progress bar or table: the one closing line")
    p.set_defaults(func=cmd_reach)
