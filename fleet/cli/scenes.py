"""`fleet check` and `fleet scenes`: validate a scene and print its capacity bound; list the bundled scenes."""

from __future__ import annotations

import argparse

from rich.table import Table

from fleet.cli.errors import (
    out,
)
from fleet.common.scene_loading import load_scene
from scenes.loader import bundled_scene_names


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
        busiest = f"{bound.busiest or '-'} {bound.bottleneck_busy_fraction:.0%} of the time"
        text += f" (the line can take them all; busiest: {busiest})"
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


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """This group's sub-commands."""
    p = sub.add_parser("check", help="validate a scene file: prints ok, or one line naming file, field and reason")
    p.add_argument("file", help="scene file path or bundled scene name")
    p.add_argument("--arms", type=int, default=None, help="arm count for scenes with an arm row")
    p.set_defaults(func=cmd_check)

    p = sub.add_parser("scenes", help="list the bundled scenes")
    p.set_defaults(func=cmd_scenes)
