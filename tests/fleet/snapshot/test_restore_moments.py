"""Snapshots at the awkward moments restore exactly: an arm mid-grasp, a part handed over between two arms (on the
pad, the second arm's task open), goals sent and not yet applied. Each restore ends with the uninterrupted run's
summary, and records, from the moment it starts, the same messages on every topic that does not follow the wall
clock."""

from __future__ import annotations

import os
import signal
import zlib
from collections import defaultdict
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest
from mcap.reader import make_reader

from fleet.monitor.replay_panel import branch_command
from fleet.record.mcap_file import Recording
from fleet.run.launcher import Launcher, RunOptions
from fleet.run.restore import restore_options, snapshot_path
from fleet.sim.sim_state import read_sim_state
from fleet.snapshot.controller_state import read_controller_state
from fleet.snapshot.coordinator_state import read_coordinator_state
from fleet.snapshot.snapshot_file import read_snapshot
from robots.phase import GRASP_PHASES
from tests.fleet.snapshot.test_restore_line import line_figures, run
from tests.fleet.test_run import QUICK_LINE

pytestmark = pytest.mark.slow

# topics whose messages follow the wall clock (heartbeats, progress, the launcher's roster, the sim's status) and the
# summary written at the end (its wall-clock figures)
WALL_TOPICS = ("status", "sim_status", "progress", "roster", "summary")


def moments(path: str) -> set[str]:
    """What is going on in a snapshot (read here from its states): an arm mid-grasp, a part handed over, goals not
    yet applied."""
    snapshot = read_snapshot(path)
    raw = {node: zlib.decompress(blob) for node, blob in snapshot.states.items()}
    sim = read_sim_state(raw.pop("sim"))
    ledger = read_coordinator_state(raw.pop("coordinator")).dispatcher.ledger
    controllers = [read_controller_state(blob, arm) for arm, blob in raw.items()]
    found = set()
    if any(c.skill.phase in GRASP_PHASES for c in controllers):
        found.add("mid-grasp")
    if any(p.location == "handover_pad" and p.part_id in ledger.open_by_part for p in ledger.parts.values()):
        found.add("mid-handover")
    if any(link.goals for link in sim.links.values()):
        found.add("goal pending")
    return found


def recorded(path: Path, from_s: float) -> dict[str, list[bytes]]:
    """Each topic's messages logged from `from_s` on (a message sent again unchanged counted once: resends follow
    the wall clock), but the wall-clock topics."""
    out: dict[str, list[bytes]] = defaultdict(list)
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages():
            if message.log_time < from_s * 1e9 or channel.topic.endswith(WALL_TOPICS):
                continue
            if not out[channel.topic] or out[channel.topic][-1] != message.data:
                out[channel.topic].append(message.data)
    return out


def test_snapshots_mid_grasp_mid_handover_and_with_goals_pending_restore_exactly(tmp_path):
    whole = run(
        RunOptions(
            scene="handover",
            duration_s=24.0,
            snapshot_every_s=1.0,
            snapshot_dir=str(tmp_path),
            record=str(tmp_path / "whole.mcap"),
        )
    )
    assert whole["status"] == "ok" and len(whole["snapshots"]) == 23 and whole["parts_completed"] >= 1
    held = {path: moments(path) for path in whole["snapshots"]}
    chosen = {}
    for moment in ("mid-grasp", "mid-handover", "goal pending"):
        found = [p for p, m in held.items() if moment in m and p not in chosen.values()]
        assert found, f"no snapshot {moment} in 23 seconds of handover: {held}"
        chosen[moment] = found[0]
    recording = Recording(tmp_path / "whole.mcap")  # it carries every snapshot, at its sim time
    assert sorted(recording.snapshot_times_ns) == [Path(p).name for p in whole["snapshots"]]
    for path in chosen.values():
        t = read_snapshot(path).sim_time_s
        assert recording.snapshot_times_ns[Path(path).name] == round(t * 1e9)
        assert "--at" in branch_command(recording, t + 0.5)
    # one moment starts from the recording (`fleet run --from RECORDING --at S`), the others from their files
    mid_grasp_s = read_snapshot(chosen["mid-grasp"]).sim_time_s
    chosen["mid-grasp"] = str(snapshot_path(tmp_path / "whole.mcap", mid_grasp_s + 0.99, tmp_path / "from"))
    assert Path(chosen["mid-grasp"]).read_bytes() == Path(whole["snapshots"][round(mid_grasp_s) - 1]).read_bytes()
    runs = [
        restore_options(path, tmp_path / moment, record=str(tmp_path / f"{moment}.mcap"))[0]
        for moment, path in chosen.items()
    ]
    with ThreadPoolExecutor(2) as pool:
        ends = list(pool.map(run, runs))
    for (moment, path), end, options in zip(chosen.items(), ends, runs):
        assert end["status"] == "ok" and end["restored_from"]["tick"] == read_snapshot(path).tick, moment
        assert line_figures(end) == line_figures(whole), moment
        start_s = read_snapshot(path).sim_time_s + 0.5  # messages of the first ticks may be logged either side
        mine, theirs = recorded(Path(options.record), start_s), recorded(tmp_path / "whole.mcap", start_s)
        assert set(mine) == set(theirs) and len(mine) >= 20, moment
        for topic in mine:
            assert mine[topic] == theirs[topic], f"{moment}: {topic}"


def test_a_snapshot_after_a_respawn_starts_each_node_in_the_incarnation_it_was_in(tmp_path):
    """A controller killed and respawned (its 2nd start) before the snapshot: the snapshot says so, the restored run
    starts it as its 2nd too (the launcher's roster and the node's own count agree), and the line goes on with
    nothing refused, respawns armed again."""
    killed, launcher_ref = [], []

    def kill_arm_0(progress) -> None:
        if not killed and progress.sim_time_s > 3.0:
            node = next(n for n in launcher_ref[0].nodes if n.name == "arm_0")
            killed.append(node.proc.pid)
            os.kill(node.proc.pid, signal.SIGKILL)

    options = RunOptions(
        scene=QUICK_LINE, duration_s=24.0, seed=5, respawn=True, snapshot_at=(18.0,), snapshot_dir=str(tmp_path)
    )
    with Launcher(options, kill_arm_0) as launcher:
        launcher_ref.append(launcher)
        whole = launcher.run()
    assert killed and whole["respawns"] == 1 and whole["snapshots"], whole["snapshots_failed"]
    assert read_snapshot(whole["snapshots"][0]).incarnations["arm_0"] == 2
    again = run(restore_options(whole["snapshots"][0], tmp_path / "scene", respawn=True)[0])
    assert again["status"] == "ok" and again["respawns"] == 0 and not again["arms_lost"]
    assert not again["refused_messages"], again["refused_messages"]
