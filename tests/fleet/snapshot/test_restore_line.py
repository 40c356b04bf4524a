"""A run restored from its own snapshot ends exactly as the run that took it: every process's state was in the file.

Lockstep, per bundled scene: one run takes snapshots at 30% and 70% of its duration; each restore runs to the same
end, and its summary equals the uninterrupted run's in every figure that is not wall-clock time. The run that takes a
snapshot goes on from the state it wrote (a world built afresh and put back), as the restored one does.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from fleet.common.scene_loading import load_checked_scene
from fleet.run.launcher import Launcher, RunOptions
from fleet.run.restore import restore_options
from fleet.snapshot.snapshot_file import read_snapshot
from scenes.loader import bundled_scene_names
from tests.fleet.test_run import WALL_FIGURES, assert_nothing_left

pytestmark = pytest.mark.slow

DURATION_S = 20.0


def run(options: RunOptions) -> dict:
    with Launcher(options) as launcher:
        summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    return summary


def line_figures(summary: dict) -> dict:
    """The summary without wall-clock figures, the snapshots taken (where, how long, how large), where it was restored
    from and what its recording holds (a restored run records from there on)."""
    skip = (*WALL_FIGURES, "restored_from", "recording")
    return {k: v for k, v in summary.items() if k not in skip and not k.startswith("snapshot")}


@pytest.mark.parametrize("scene", bundled_scene_names())
def test_a_run_restored_at_30_and_70_percent_ends_as_the_uninterrupted_run(scene, tmp_path):
    at = (0.3 * DURATION_S, 0.7 * DURATION_S)
    whole = run(RunOptions(scene=scene, duration_s=DURATION_S, snapshot_at=at, snapshot_dir=str(tmp_path)))
    assert whole["status"] == "ok" and not whole["snapshots_failed"]
    hz = load_checked_scene(scene).control_hz
    assert [Path(p).name for p in whole["snapshots"]] == [f"snapshot-{round(t * hz):09d}.clawsnap" for t in at]
    assert all(read_snapshot(p).arms == whole["arm_ids"] for p in whole["snapshots"]), "in the scene's order"
    restored = [restore_options(path, tmp_path / f"scene_{i}")[0] for i, path in enumerate(whole["snapshots"])]
    with ThreadPoolExecutor(2) as pool:
        ends = list(pool.map(run, restored))
    for end in ends:
        assert end["status"] == "ok" and end["sim_seconds"] == pytest.approx(DURATION_S)
        assert line_figures(end) == line_figures(whole)


def test_a_run_with_a_faulty_network_restored_ends_as_the_uninterrupted_run(tmp_path):
    """States and frames delayed on their links are still on their way at the cut: they name the snapshot being
    taken (sampled before it), reach their nodes after it, and neither the run that took it nor the restored one
    holds anything for it again; the restored run keeps the links' faults (they are the sim's state)."""
    faults = {"latency_ms": 30.0, "jitter_ms": 10.0}
    whole = run(RunOptions(scene="handover", duration_s=14.0, snapshot_at=(6.0,), snapshot_dir=str(tmp_path), **faults))
    assert whole["status"] == "ok" and not whole["snapshots_failed"] and not whole["arms_lost"]
    end = run(restore_options(whole["snapshots"][0], tmp_path / "scene")[0])
    assert end["status"] == "ok" and not end["arms_lost"]
    assert line_figures(end) == line_figures(whole)
