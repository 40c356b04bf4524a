"""A run started from a snapshot: the launcher's options for it (its scene, written out of the snapshot, its seed and
arm count, its end), whoever starts it (`fleet run --from`, a sweep, a test)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from fleet.run.launcher import RunOptions
from fleet.snapshot.snapshot_file import RunSnapshot, read_snapshot


def restore_options(
    path: str | Path, folder: Path, duration_s: float | None = None, **options
) -> tuple[RunOptions, RunSnapshot]:
    """Options that start every process from the snapshot at `path` (its scene and robot files written under
    `folder`, which must outlive the run), running to where the snapshot's run was to end, or `duration_s` sim
    seconds more; `options` sets the rest (another allocator, `reseed`: a branch; `mode`: lockstep by default, and
    only lockstep repeats). A `SnapshotError` (one line) if it cannot."""
    snapshot = read_snapshot(path)
    scene = snapshot.scene.write(Path(folder))
    seconds_per_tick = snapshot.sim_time_s / snapshot.tick
    end_s = snapshot.end_tick * seconds_per_tick if duration_s is None else snapshot.sim_time_s + duration_s
    base = RunOptions(
        scene=str(scene),
        arms=snapshot.scene.arms,
        seed=snapshot.scene.seed,
        duration_s=end_s,
        allocator=snapshot.allocator,
        restore_from=str(Path(path).resolve()),
    )
    return dataclasses.replace(base, **options), snapshot
