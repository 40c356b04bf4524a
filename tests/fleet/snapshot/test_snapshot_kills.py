"""A snapshot taken while a node dies is either whole (every part from the start of its node that ran at the cut)
and restores, or listed in `snapshots_failed` with the reason: never a file that cannot be restored."""

from __future__ import annotations

import os
import signal

import pytest

from fleet.bus.keys import Keys
from fleet.bus.session import open_session
from fleet.run.launcher import Launcher, RunOptions
from fleet.run.restore import restore_options
from fleet.snapshot.snapshot_file import read_snapshot
from tests.fleet.sim_time_trigger import SimTimeTrigger
from tests.fleet.test_run import QUICK_LINE, assert_nothing_left

pytestmark = pytest.mark.slow

SNAPSHOT_S = 6.0


def run_with_a_kill(node: str, at_s: float, respawn: bool, out) -> dict:
    """The quick line with a snapshot at 6 s, `node` killed (SIGKILL) once the line passes `at_s`."""
    options = RunOptions(
        scene=QUICK_LINE, duration_s=9.0, seed=5, respawn=respawn, snapshot_at=(SNAPSHOT_S,), snapshot_dir=str(out)
    )
    with Launcher(options) as launcher:
        victim = next(n for n in launcher.nodes if n.name == node)
        with (
            open_session(launcher.client_endpoints("monitor")) as session,
            SimTimeTrigger(session, Keys(options.run_id), [at_s], lambda: os.kill(victim.proc.pid, signal.SIGKILL)),
        ):
            summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    return summary


@pytest.mark.parametrize(
    ("node", "at_s", "respawn"),
    [
        ("coordinator", SNAPSHOT_S - 0.02, True),
        ("coordinator", SNAPSHOT_S, True),
        ("arm_0", SNAPSHOT_S - 0.02, True),
        ("arm_0", SNAPSHOT_S, True),
        ("arm_0", SNAPSHOT_S + 0.02, False),
        ("coordinator", SNAPSHOT_S + 0.02, True),
    ],
    ids=[
        "coordinator-before-respawn",
        "coordinator-at-respawn",
        "controller-before-respawn",
        "controller-at-respawn",
        "controller-after",
        "coordinator-after-respawn",
    ],
)
def test_a_snapshot_taken_as_a_node_dies_restores_or_says_why_it_failed(node, at_s, respawn, tmp_path):
    summary = run_with_a_kill(node, at_s, respawn, tmp_path / "snapshots")
    written, failed = summary["snapshots"], summary["snapshots_failed"]
    assert len(written) + len(failed) == 1, (written, failed)
    if failed:
        assert failed[0].startswith("tick 600: ") and len(failed[0]) > len("tick 600: "), failed
        return
    snapshot = read_snapshot(written[0])
    assert snapshot.tick == 600
    options, _ = restore_options(written[0], tmp_path / "restore", duration_s=2.0)
    with Launcher(options) as launcher:
        restored = launcher.run()
    assert_nothing_left(restored, launcher.endpoint)
    assert restored["status"] == "ok", restored["error"]
    assert not [e for e in restored["arm_events"] if e["event"] == "lost"], restored["arm_events"]
