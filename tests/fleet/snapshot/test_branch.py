"""Branching: a sweep from one snapshot compares allocators from one identical state. The runs of one seed draw the
same arrivals after the snapshot whatever the allocator (so they pair); another seed draws others; every run starts
at the snapshot's tick with the history before it in common. A branch may run a faster or slower belt."""

from __future__ import annotations

import math
from collections import Counter

import msgspec
import pytest

from fleet.bus.messages import PartsState
from fleet.record.mcap_file import Recording
from fleet.run.launcher import RunOptions
from fleet.run.restore import restore_options
from fleet.snapshot.snapshot_file import read_snapshot
from fleet.sweep.grid import grid
from fleet.sweep.results import cell_rows, pair_rows, run_rows
from fleet.sweep.runner import load_results, run_local
from tests.fleet.snapshot.test_restore_line import line_figures, run

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


def _belt_speeds_m_per_s(path) -> list[float]:
    """The speeds of the parts riding the belt, as the recording's parts messages had them (every sample)."""
    recording = Recording(path)
    key = next(k for k in recording.raw_keys if k.endswith("world/parts"))
    speeds = []
    for message in recording.raw_messages([key]):
        parts = msgspec.msgpack.decode(message.payload, type=PartsState)
        for i in range(len(parts.part_ids)):
            vx, vy, vz = parts.velocities[3 * i : 3 * i + 3]
            if abs(vz) < 1e-3 and 0.02 < math.hypot(vx, vy) < 0.3:  # carried along, not falling or in a claw
                speeds.append(round(math.hypot(vx, vy), 2))
    return speeds


def test_a_branch_with_a_faster_belt_moves_the_parts_faster_and_the_coordinator_knows(tmp_path):
    """`--set conveyor.speed_m_per_s` on a restore: the sim's belt and the coordinator's bound follow the new speed;
    set to the speed it had, the branch ends exactly as the run that took the snapshot."""
    whole = run(RunOptions(scene="sorting_line", duration_s=16.0, snapshot_at=(8.0,), snapshot_dir=str(tmp_path / "s")))
    snapshot = whole["snapshots"][0]
    same, _ = restore_options(snapshot, tmp_path / "same", overrides={"conveyor.speed_m_per_s": 0.06})
    faster, _ = restore_options(
        snapshot, tmp_path / "faster", overrides={"conveyor.speed_m_per_s": 0.1}, record=str(tmp_path / "f.mcap")
    )
    ends = [run(same), run(faster)]
    assert line_figures(ends[0]) == line_figures(whole), "the speed it had: the branch is the run itself"
    assert ends[1]["status"] == "ok" and ends[1]["inter_arm_contacts"] == 0
    assert ends[1]["capacity"] != whole["capacity"], "the coordinator's bound follows the belt"
    speeds = Counter(_belt_speeds_m_per_s(tmp_path / "f.mcap"))
    assert speeds.most_common(1)[0][0] == pytest.approx(0.1, abs=0.01), speeds
