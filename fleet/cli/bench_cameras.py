"""`fleet bench cameras`: frames per second by image size and number of cameras (docs/benchmarks.md)."""

from __future__ import annotations

import argparse

from rich.table import Table

from fleet.cli.errors import UsageError


def size_px(text: str) -> tuple[int, int]:
    """`WxH` in pixels, e.g. 320x240."""
    try:
        width, height = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give a size as WIDTHxHEIGHT, e.g. 320x240") from None
    if not (8 <= width <= 1920 and 8 <= height <= 1080):
        raise argparse.ArgumentTypeError(f"{text!r}: 8x8 to 1920x1080")
    return width, height


def cmd_bench_cameras(args: argparse.Namespace) -> int:
    from fleet.bench.cameras import bench_env_cameras
    from fleet.sim.render import RenderUnavailable

    try:
        if args.env:
            return print_env_row(
                bench_env_cameras(args.env_arms, args.env_size, args.env_steps, shadows=args.shadows), args.json
            )
        if args.line:
            return print_line_rows(args)
        return print_frame_rows(args)
    except RenderUnavailable as exc:
        raise UsageError(str(exc)) from None


def print_frame_rows(args: argparse.Namespace) -> int:
    """Frames per second for every count of cameras and size asked for."""
    from fleet.bench.cameras import bench_cameras
    from fleet.cli.bench import print_bench

    table = Table("size", "cameras", "images", "ms per pass", "frames/s", "first frame s")
    rows = []
    for count in args.cameras:
        for size in args.sizes:
            row = bench_cameras(size, count, args.images, args.frames)
            rows.append(row)
            table.add_row(
                f"{row.width_px}x{row.height_px}",
                str(count),
                row.images,
                f"{row.ms_per_pass:.1f}",
                f"{row.frames_per_s:.1f}",
                f"{row.first_frame_s:.1f}",
            )
    return print_bench(table, rows, args.json)


def print_line_rows(args: argparse.Namespace) -> int:
    """The lockstep line's loop wall time without and with one camera of each size asked for."""
    from fleet.bench.cameras import bench_line_cameras
    from fleet.cli.bench import print_bench

    table = Table("camera", "frames", "loop s without", "loop s with", "with / without", "render s", "added / render")
    rows = []
    for size in args.sizes:
        row = bench_line_cameras(
            size, args.images, args.line_rate, args.line_arms, args.line_seconds, args.shadows, args.line_encoding
        )
        rows.append(row)
        table.add_row(
            f"{row.width_px}x{row.height_px} {row.images} {row.rate_hz:g} Hz {row.encoding}"
            f"{'' if row.shadows else ', no shadows'}",
            str(row.frames),
            f"{row.loop_without_s:.1f}",
            f"{row.loop_with_s:.1f}",
            f"{row.ratio:.2f}",
            f"{row.render_s:.1f}",
            f"{row.added_over_render:.2f}",
        )
    return print_bench(table, rows, args.json)


def print_env_row(row, as_json: bool) -> int:
    """The env's agent-steps/s without and with a wrist camera on every arm."""
    from fleet.cli.bench import print_bench

    table = Table("env", "arms", "wrist camera", "agent-steps/s without", "agent-steps/s with", "with / without")
    table.add_row(
        "reach",
        str(row.arms),
        f"{row.size_px}x{row.size_px} rgbd{'' if row.shadows else ', no shadows'}",
        f"{row.agent_steps_per_s_without:.0f}",
        f"{row.agent_steps_per_s:.0f}",
        f"{row.agent_steps_per_s / row.agent_steps_per_s_without:.2f}",
    )
    return print_bench(table, [row], as_json)


def add_parser(bench: argparse._SubParsersAction) -> None:
    from fleet.bench.camera_choices import IMAGES, SIZES

    b = bench.add_parser("cameras", help="camera frames/s by size and number of cameras (rendering on CPU or GPU)")
    b.add_argument("--sizes", type=size_px, nargs="+", default=list(SIZES), help="WIDTHxHEIGHT each")
    b.add_argument("--cameras", type=int, nargs="+", default=[1, 4], choices=range(1, 17), metavar="N")
    b.add_argument("--images", choices=sorted(IMAGES), default="rgbd", help="rgb, rgbd (rgb + depth) or all")
    b.add_argument("--frames", type=int, default=20, help="renders timed per row")
    b.add_argument(
        "--env", action="store_true", help="instead: the env's agent-steps/s on reach, with and without wrist cameras"
    )
    b.add_argument(
        "--line",
        action="store_true",
        help="instead: a lockstep sorting line's loop wall time without and with one camera of each --sizes",
    )
    b.add_argument("--line-arms", type=int, default=4, choices=range(1, 13), metavar="N")
    b.add_argument("--line-rate", type=float, default=5.0, help="the line camera's rate (sim Hz)")
    b.add_argument("--line-seconds", type=float, default=30.0, help="sim seconds of each line")
    b.add_argument(
        "--line-encoding",
        choices=("auto", "png", "jpeg", "raw"),
        default="auto",
        help="the line's --camera-encoding (auto: raw, the line's bus being on this machine)",
    )
    b.add_argument("--env-arms", type=int, default=4, choices=range(1, 13), metavar="N")
    b.add_argument("--env-size", type=int, default=64, help="the wrist cameras' width and height (px)")
    b.add_argument("--env-steps", type=int, default=200)
    b.add_argument(
        "--shadows",
        dest="shadows",
        action="store_const",
        const=True,
        default="auto",
        help="--env and --line: the light casts shadows even on a CPU renderer (default: appearance.shadows auto)",
    )
    b.add_argument(
        "--no-shadows",
        dest="shadows",
        action="store_const",
        const=False,
        help="--env and --line: the light casts no shadows, even on a GPU",
    )
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_cameras)
