"""`fleet bench perception`: how well the perception library sees each scene's parts through its fixed cameras
(docs/perception.md, docs/benchmarks.md)."""

from __future__ import annotations

import argparse

from rich.table import Table

from fleet.cli.errors import UsageError


def cmd_bench_perception(args: argparse.Namespace) -> int:
    from fleet.bench.perception import bench_perception
    from fleet.cli.bench import print_bench
    from fleet.sim.render import RenderUnavailable
    from scenes.loader import bundled_scene_names

    table = Table("scene", "seed", "camera", "frames", "parts seen", "recall", "precision", "error mm p50 / p95")
    table.add_column("yaw error deg p50 / p95")
    table.add_column("detect ms")
    rows = []
    for scene in args.scenes or bundled_scene_names():
        for seed in args.seeds:
            try:
                found = bench_perception(scene, args.seconds, args.scale, seed, args.randomise_appearance)
            except RenderUnavailable as exc:
                raise UsageError(str(exc)) from None
            rows += found
    for row in rows:
        table.add_row(
            row.scene,
            f"{row.seed}{' drawn' if row.randomised else ''}",
            f"{row.camera} {row.width_px}x{row.height_px}",
            str(row.frames),
            str(row.parts_visible),
            f"{row.recall:.3f}",
            f"{row.precision:.3f}",
            f"{row.error_p50_mm} / {row.error_p95_mm}",
            f"{row.yaw_error_p50_deg} / {row.yaw_error_p95_deg}",
            f"{row.detect_ms:.1f}",
        )
    return print_bench(table, rows, args.json)


def add_parser(bench: argparse._SubParsersAction) -> None:
    b = bench.add_parser(
        "perception", help="perception's recall, precision and pose error through each scene's fixed cameras"
    )
    b.add_argument("--scenes", nargs="+", help="scene names or files (default: every bundled scene)")
    b.add_argument("--seconds", type=float, default=20.0, help="sim seconds of each scene (arms at home)")
    b.add_argument(
        "--scale", type=float, default=1.0, help="each camera's width and height times this (same view, finer pixels)"
    )
    b.add_argument("--seeds", type=int, nargs="+", default=[0], help="a row for each seed (default: 0)")
    b.add_argument(
        "--randomise-appearance",
        action="store_true",
        help="draw what the cameras see from each seed: light, belt grey, part shade, camera shifts (docs/scenes.md)",
    )
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_perception)
