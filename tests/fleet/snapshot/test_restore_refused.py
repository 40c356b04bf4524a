"""A restore that cannot start says so in one line, at once: a snapshot missing a node's state is refused before any
process starts, and a node whose state cannot be read back ends the run with its own line, not after the line has
waited for it. A node restarted in a restored run takes over the running line; it never starts from the snapshot
again."""

from __future__ import annotations

import zlib

import msgspec
import pytest

from fleet.bus.keys import Keys
from fleet.bus.session import open_session
from fleet.cli import main
from fleet.run.launcher import Launcher, RunOptions
from fleet.run.restore import restore_options
from fleet.snapshot.snapshot_file import SnapshotError, read_snapshot, write_snapshot
from tests.fleet.sim_time_trigger import SimTimeTrigger
from tests.fleet.test_run import QUICK_LINE, assert_nothing_left

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def taken(tmp_path_factory) -> str:
    """A sound snapshot of the quick line at 2 s."""
    out = tmp_path_factory.mktemp("taken")
    options = RunOptions(scene=QUICK_LINE, duration_s=2.5, seed=3, snapshot_at=(2.0,), snapshot_dir=str(out))
    with Launcher(options) as launcher:
        summary = launcher.run()
    assert summary["status"] == "ok" and len(summary["snapshots"]) == 1, summary
    return summary["snapshots"][0]


def edited(taken: str, path, node: str, state: bytes | None) -> str:
    """`taken` with `node`'s state replaced (None: left out), written to `path`."""
    snapshot = read_snapshot(taken)
    states = {n: s for n, s in snapshot.states.items() if n != node}
    if state is not None:
        states[node] = state
    write_snapshot(msgspec.structs.replace(snapshot, states=states), path)
    return str(path)


@pytest.mark.parametrize("node", ["arm_1", "coordinator"])
def test_a_snapshot_without_a_node_s_state_is_refused_before_anything_starts(node, taken, tmp_path, capsys):
    path = edited(taken, tmp_path / "short.clawsnap", node, None)
    with pytest.raises(SnapshotError, match=f"holds no state for '?{node}"):
        restore_options(path, tmp_path / "restore")
    assert main(["run", "--from", path, "--duration", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "holds no state for" in err[0] and node in err[0], err


@pytest.mark.parametrize("node", ["arm_1", "coordinator"])
def test_a_node_that_cannot_read_its_state_back_ends_the_restore_with_its_own_line(node, taken, tmp_path):
    path = edited(taken, tmp_path / "damaged.clawsnap", node, zlib.compress(b"not a state"))
    options, _ = restore_options(path, tmp_path / "restore", duration_s=1.0, respawn=True)
    with Launcher(options) as launcher:
        summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert summary["status"] == "error"
    # the node's own reason, not the sim's, which would come only after it waited for the node a minute
    assert summary["error"].startswith(f"{node} could not start (exit 2): "), summary["error"]
    assert (
        "cannot read back the state" in summary["error"] and "did not start from the snapshot" not in summary["error"]
    )


def test_a_node_restarted_in_a_restored_run_takes_over_and_never_restores_again(taken, tmp_path):
    options, snapshot = restore_options(taken, tmp_path / "restore", duration_s=4.0, respawn=True)
    with Launcher(options) as launcher:
        arm = next(n for n in launcher.nodes if n.name == "arm_0")
        first = list(arm.child.argv)
        with (
            open_session(launcher.client_endpoints("monitor")) as session,
            SimTimeTrigger(session, Keys(options.run_id), [snapshot.sim_time_s + 0.3], arm.child.kill),
        ):
            summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert "--from" in first and "--from" not in arm.child.argv, arm.child.argv
    assert arm.starts == 2 and arm.child.argv[-2:] == ["--incarnation", "2"]
    assert summary["status"] == "ok", summary["error"]
    assert summary["respawns"] == 1, summary["respawns"]
