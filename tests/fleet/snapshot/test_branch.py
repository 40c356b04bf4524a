"""Branching: a sweep from one snapshot compares allocators from one identical state. The runs of one seed draw the
same arrivals after the snapshot whatever the allocator (so they pair); another seed draws others; every run starts
at the snapshot's tick with the history before it in common."""

from __future__ import annotations

import pytest

from fleet.run.launcher import RunOptions
from fleet.snapshot.snapshot_file import read_snapshot
from fleet.sweep.grid import grid
from fleet.sweep.results import cell_rows, pair_rows, run_rows
from fleet.sweep.runner import load_results, run_local
from tests.fleet.snapshot.test_restore_line import run

pytestmark = pytest.mark.slow


def test_a_sweep_branches_allocators_and_seeds_from_one_snapshot(tmp_path):
    whole = run(
        RunOptions(scene="mixed_infeed", duration_s=24.0, snapshot_at=(12.0,), snapshot_dir=str(tmp_path / "snap"))
    )
    snapshot = whole["snapshots"][0]
    tick = read_snapshot(snapshot).tick
    cells = grid("mixed_infeed", [0, 1], ["optimal", "greedy"], None, restore_from=snapshot)  # to the run's end
    run_local(cells, tmp_path / "sweep", 2, lambda cell, summary: None)
    results = {(r["cell"]["seed"], r["cell"]["allocator"]): r["summary"] for r in load_results(tmp_path / "sweep")}
    assert len(results) == 4 and all(s["status"] == "ok" for s in results.values())
    assert all(s["restored_from"]["tick"] == tick and s["sim_seconds"] == pytest.approx(24.0) for s in results.values())
    assert all(s["allocator"] == allocator for (_, allocator), s in results.items())
    spawned = {key: s["parts_spawned"] for key, s in results.items()}
    assert spawned[(0, "optimal")] == spawned[(0, "greedy")] and spawned[(1, "optimal")] == spawned[(1, "greedy")], (
        "one seed, one set of arrivals after the snapshot, whatever the allocator"
    )
    arrivals = {
        seed: (
            results[(seed, "optimal")]["parts_spawned"],
            results[(seed, "optimal")]["capacity_of_run"]["arrivals_per_min"],
        )
        for seed in (0, 1)
    }
    assert arrivals[0] != arrivals[1], "each seed draws its own arrivals after the snapshot"
    rows = run_rows(load_results(tmp_path / "sweep"))
    assert {r["from"] for r in rows} == {f"snapshot-{tick:09d}.clawsnap"}
    assert {c["allocator"]: c["runs"] for c in cell_rows(rows)} == {"optimal": 2, "greedy": 2}
    assert [p["seeds"] for p in pair_rows(rows)] == [2], "the allocators pair over the same two seeds"
