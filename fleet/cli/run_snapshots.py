"""`fleet run`'s snapshot flags: `--snapshot-at T1,T2`, `--snapshot-every S` (written under `--out DIR`), and
`--from SNAPSHOT` (the run starts where the snapshot was taken, with the scene the snapshot holds)."""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path

from fleet.cli.errors import UsageError, positive_numbers
from fleet.snapshot.snapshot_file import SnapshotError

DEFAULT_DURATION_S = 120.0
SNAPSHOT_FOLDER = "snapshots"


def sim_seconds_list(text: str) -> tuple[float, ...]:
    """`--snapshot-at 30,70.5`: positive sim seconds, comma-separated."""
    return tuple(positive_numbers(text, "positive sim seconds separated by commas, e.g. 30,70"))


def add_snapshot_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--snapshot-at",
        type=sim_seconds_list,
        metavar="S,S,...",
        default=(),
        help="take a snapshot of the whole run at these sim seconds (into --out DIR/snapshots; with --out, the "
        "monitor's button takes one when asked)",
    )
    p.add_argument("--snapshot-every", type=float, metavar="S", help="take a snapshot every S sim seconds (with --out)")
    p.add_argument(
        "--from",
        dest="from_snapshot",
        metavar="SNAPSHOT",
        help="start every process from a snapshot, or from one a recording carries (its scene and seed; --duration: "
        "sim seconds from there, default to where the snapshot's run was to end; another --allocator branches)",
    )
    p.add_argument(
        "--at",
        type=float,
        metavar="S",
        help="with --from RECORDING: the newest snapshot it carries at or before S sim seconds (default: its last)",
    )
    p.add_argument(
        "--set",
        action="append",
        type=scene_setting,
        metavar="FIELD.PATH=V",
        help="with --from: a field of the snapshot's scene set otherwise from there on (a branch), e.g. "
        "conveyor.speed_m_per_s=0.05; only fields a restored run reads afresh",
    )


def scene_setting(text: str) -> tuple[str, object]:
    """`--set conveyor.speed_m_per_s=0.05`: a dotted field path and one value, read as a sweep reads its `--set`
    (argparse's `type`)."""
    from fleet.sweep.grid import GridError, Override

    try:
        setting = Override.parse(text)
    except GridError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
    if len(setting.values) != 1:
        raise argparse.ArgumentTypeError(
            f"{text!r}: one value (a sweep takes several), e.g. conveyor.speed_m_per_s=0.05"
        )
    return setting.path, setting.values[0]


def check_snapshot_flags(args: argparse.Namespace) -> None:
    """Snapshot flags that cannot work, refused in one line."""
    wanted = bool(args.snapshot_at or args.snapshot_every is not None)
    if args.snapshot_every is not None and not (math.isfinite(args.snapshot_every) and args.snapshot_every > 0):
        raise UsageError(f"--snapshot-every {args.snapshot_every:g}: give a positive number of sim seconds")
    if wanted and not args.out:
        raise UsageError("--snapshot-at/--snapshot-every write into --out DIR: give it")
    if getattr(args, "perception", "truth") != "truth" and (wanted or getattr(args, "from_snapshot", None)):
        raise UsageError("--perception cameras: a line working from its cameras cannot be snapshotted or restored yet")


def restore_refused_flags(args: argparse.Namespace) -> list[tuple[str, bool]]:
    """The flags of `fleet run` a restored run cannot take, and whether each was given: what its processes hold
    from the snapshot's start (the arms and seed, the bus's faults in flight, the coordinator's pipeline) would
    take them in some processes and not others. A branch changes the allocator, the mode or the belt's speed
    (`--set`)."""
    return [
        ("--arms", args.arms is not None),
        ("--seed", args.seed is not None),
        ("--latency-ms", getattr(args, "latency_ms", None) is not None),
        ("--jitter-ms", getattr(args, "jitter_ms", None) is not None),
        ("--loss", getattr(args, "loss", None) is not None),
        ("--no-pipeline", not getattr(args, "pipeline", True)),
    ]


def open_snapshot(args: argparse.Namespace) -> tempfile.TemporaryDirectory | None:
    """With `--from`: `args` made to run the snapshot's scene (written into a temporary folder, returned for the
    caller to remove), seed and allocator (unless `--allocator` branches) from its tick to its run's end or
    `--duration` more; without, the defaults of a fresh run."""
    from fleet.run.restore import check_same_scene, restore_options, snapshot_path

    if args.at is not None and not args.from_snapshot:
        raise UsageError("--at picks a snapshot in the recording given with --from: give --from RECORDING")
    if args.set and not args.from_snapshot:
        raise UsageError(
            "--set changes a snapshot's scene from there on: give --from SNAPSHOT (a fresh run's is set "
            "in its scene file, or over a grid by fleet sweep --set)"
        )
    args.incarnations = ()
    if not args.from_snapshot:
        args.scene = args.scene_label = args.scene or "assembly_line"
        args.duration = DEFAULT_DURATION_S if args.duration is None else args.duration
        args.allocator = args.allocator or "optimal"
        return None
    for flag, given in restore_refused_flags(args):
        if given:
            raise UsageError(f"--from starts the snapshot's own line: leave out {flag}")
    folder = tempfile.TemporaryDirectory(prefix="clawfleet-snapshot-")
    try:
        path = snapshot_path(args.from_snapshot, args.at, Path(folder.name) / "from")
        options, snapshot = restore_options(path, Path(folder.name), args.duration, dict(args.set or ()))
    except (SnapshotError, OSError) as exc:
        folder.cleanup()
        raise UsageError(str(exc)) from None
    if args.scene:  # compared by content: a scene given beside a snapshot must be the snapshot's own
        try:
            check_same_scene(args.scene, snapshot, Path(folder.name) / "compared")
        except SnapshotError as exc:
            folder.cleanup()
            raise UsageError(str(exc)) from None
    args.scene, args.arms, args.seed, args.duration = options.scene, options.arms, options.seed, options.duration_s
    settings = "".join(f", {k}={v}" for k, v in args.set or ())
    args.scene_label = f"{snapshot.scene_name} from {snapshot.sim_time_s:g} s{settings}"
    args.allocator = args.allocator or options.allocator
    args.from_snapshot, args.incarnations = options.restore_from, options.incarnations
    return folder


def snapshot_options(args: argparse.Namespace) -> dict:
    """The launcher's snapshot options from the flags."""
    # with --out, snapshots asked for while the line runs (the monitor's button) have somewhere to go too
    folder = Path(args.out) / SNAPSHOT_FOLDER if args.out else None
    return {
        "snapshot_at": tuple(args.snapshot_at),
        "snapshot_every_s": args.snapshot_every,
        "snapshot_dir": str(folder.resolve()) if folder else None,  # made by the sim when it writes one
        "restore_from": args.from_snapshot,
        "incarnations": args.incarnations,  # after a respawn, the start each node was in
    }
