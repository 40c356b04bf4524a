"""`fleet bench snapshot`: what a snapshot costs a lockstep line (how long the line stands still, how large the
file) and what a restore costs (wall time until every process is back), on the sorting line; and whether the
restored run ends as the run that took the snapshot."""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from fleet.run.launcher import Launcher, RunOptions
from fleet.run.restore import restore_options

WALL = ("wall", "latency", "round_trip", "processes", "bus_messages", "decision_wall_ms", "lockstep_timeouts")


@dataclass
class SnapshotBenchRow:
    arms: int
    snapshots: int
    stall_ms_max: float
    stall_ms_median: float
    stall_ms_by_stage: dict[str, float] = field(default_factory=dict)
    next_ticks_ms_median: float | None = None  # how much longer the ticks after one took (nodes writing states)
    next_ticks_ms_max: float | None = None
    bytes_max: int = 0
    write_ms_max: float = 0.0  # on a thread of its own, while the line goes on
    restore_to_first_tick_s: float = 0.0  # reading the file, every process back (the sim's count)
    restore_command_s: float = 0.0  # the launcher's whole restored run, to the end
    restored_ends_the_same: bool = False


def _line_figures(summary: dict) -> dict:
    skip = ("restored_from", "recording")
    return {
        k: v
        for k, v in summary.items()
        if k not in skip and not k.startswith("snapshot") and not any(w in k for w in WALL)
    }


def bench_snapshots(arms: int, seconds: float, snapshots: int) -> SnapshotBenchRow:
    """A `seconds` lockstep run of the sorting line with `arms` arms taking `snapshots` evenly spaced snapshots,
    then a run restored from the first of them."""
    with tempfile.TemporaryDirectory(prefix="clawfleet-bench-snapshot-") as tmp:
        at = tuple(round(seconds * (i + 1) / (snapshots + 1), 2) for i in range(snapshots))
        options = RunOptions(scene="sorting_line", arms=arms, duration_s=seconds, snapshot_at=at, snapshot_dir=tmp)
        with Launcher(options, on_message=lambda _text: None) as launcher:
            whole = launcher.run()
        if whole["status"] != "ok" or len(whole["snapshots"]) != snapshots:
            raise RuntimeError(f"the run with snapshots ended {whole['status']}: {whole.get('snapshots_failed')}")
        restored, _ = restore_options(whole["snapshots"][0], Path(tmp) / "scene")
        with Launcher(restored, on_message=lambda _text: None) as launcher:
            again = launcher.run()
    return SnapshotBenchRow(
        arms,
        snapshots,
        whole["snapshot_stall_ms_max"],
        whole["snapshot_stall_ms_median"],
        whole["snapshot_stall_ms_by_stage"],
        whole["snapshot_next_ticks_ms_median"],
        whole["snapshot_next_ticks_ms_max"],
        whole["snapshot_bytes_max"],
        whole["snapshot_write_ms_max"],
        again["restored_from"]["wall_s"],
        again["wall_seconds"],
        _line_figures(again) == _line_figures(whole),
    )
