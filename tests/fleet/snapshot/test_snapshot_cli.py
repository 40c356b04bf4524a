"""`fleet run` and `fleet sweep` refuse snapshot flags that cannot work in one line, exit 2, starting nothing."""

from __future__ import annotations

import re
import zlib

import pytest

from fleet.cli import main
from fleet.common.scene_loading import load_checked_scene
from fleet.record.mcap_file import RecordingWriter
from fleet.snapshot.snapshot_file import RunSnapshot, SceneSource, write_snapshot
from scenes.loader import resolve_scene_path


@pytest.fixture
def snapshot(tmp_path) -> str:
    """A sound file of pick_cell (its states are never read: every command here is refused before)."""
    path = tmp_path / "pick.clawsnap"
    states = {n: zlib.compress(b"x") for n in ("sim", "coordinator", "arm_0")}
    write_snapshot(
        RunSnapshot("pick_cell", SceneSource.of("pick_cell", None, 0), "lockstep", 500, 5.0, 3000, "greedy", states),
        path,
    )
    return str(path)


CASES = [
    (["run", "--from", "{missing}"], "no such snapshot file"),
    (["run", "--from", "{bad}"], "not a clawfleet snapshot"),
    (["run", "sorting_line", "--from", "{snapshot}"], "sorting_line: name is 'sorting_line' where the snapshot's"),
    (["run", "{slower}", "--from", "{snapshot}"], "conveyor.speed_m_per_s is 0.01 where the snapshot's scene has"),
    (["run", "--from", "{snapshot}", "--arms", "3"], "leave out --arms"),
    (["run", "--snapshot-at", "5"], "write into --out DIR"),
    (["run", "--snapshot-every", "0", "--out", "{dir}"], "--snapshot-every 0"),
    (["sweep", "--from", "{snapshot}", "--set", "seed=1,2", "--out", "{dir}"], "can set only conveyor.speed_m_per_s"),
    (["sweep", "--from", "{snapshot}", "--load", "1.0", "--out", "{dir}"], "leave out --load"),
    (["run", "--from", "{snapshot}", "--set", "stations.0.pose.xyz=1"], "can set only conveyor.speed_m_per_s"),
    (["run", "--set", "conveyor.speed_m_per_s=0.1"], "give --from SNAPSHOT"),
    (["run", "--from", "{snapshot}", "--set", "arms.0.base.xyz=[0,0,0]"], "can set only conveyor.speed_m_per_s"),
    (["run", "--from", "{snapshot}", "--set", "arms.0.base.xyz=[0,0"], "is not a YAML value"),
    (["run", "--from", "{snapshot}", "--latency-ms", "20"], "leave out --latency-ms"),
    (["run", "--from", "{snapshot}", "--loss", "0.1"], "leave out --loss"),
    (["run", "--from", "{snapshot}", "--no-pipeline"], "leave out --no-pipeline"),
    (["run", "--from", "{snapshot}", "--set", "conveyor.speed_m_per_s=-1"], "conveyor.speed_m_per_s"),
    (["sweep", "--from", "{missing}", "--out", "{dir}"], "no such snapshot file"),
    (["sweep", "--out", "{dir}"], "give a scene"),
    (["run", "--at", "3"], "give --from RECORDING"),
    (["run", "--from", "{snapshot}", "--at", "3"], "is a snapshot file itself"),
    (["run", "--from", "{recording}"], "no snapshot (it carries: none)"),
    (["run", "--from", "{recording}", "--at", "2"], "no snapshot at or before 2 s"),
]


@pytest.mark.parametrize(("argv", "says"), CASES, ids=lambda v: " ".join(v) if isinstance(v, list) else None)
def test_a_snapshot_flag_that_cannot_work_is_one_line_and_exit_2(argv, says, snapshot, tmp_path, capsys):
    (tmp_path / "bad.clawsnap").write_bytes(b"PK\x03\x04" * 20)
    with RecordingWriter(tmp_path / "plain.mcap", load_checked_scene("pick_cell").model_dump_json(), "line"):
        pass  # a recording that carries no snapshot
    slower = tmp_path / "edited" / "pick_cell.yaml"  # the same file name, a slower belt
    slower.parent.mkdir()
    text = resolve_scene_path("pick_cell").read_text()
    slower.write_text(re.sub(r"speed_m_per_s: [0-9.]+", "speed_m_per_s: 0.01", text))
    names = {
        "slower": str(slower),
        "snapshot": snapshot,
        "missing": str(tmp_path / "none.clawsnap"),
        "bad": str(tmp_path / "bad.clawsnap"),
        "recording": str(tmp_path / "plain.mcap"),
    }
    try:
        code = main([a.format(dir=str(tmp_path / "out"), **names) for a in argv])
    except SystemExit as exc:  # refused by the argument parser itself
        code = exc.code
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and says in err[-1] and len(err) == 1, err


def test_fleet_run_from_a_snapshot_starts_each_node_in_the_incarnation_it_was_in(tmp_path):
    """What `fleet run --from` hands the launcher: the snapshot's scene, seed, allocator and its nodes' starts."""
    from fleet.cli import build_parser
    from fleet.cli.run_snapshots import open_snapshot, snapshot_options

    path = tmp_path / "respawned.clawsnap"
    states = {n: zlib.compress(b"x") for n in ("sim", "coordinator", "arm_0")}
    scene = SceneSource.of("pick_cell", None, 0)
    snapshot = RunSnapshot("pick_cell", scene, "lockstep", 500, 5.0, 3000, "greedy", states, incarnations={"arm_0": 2})
    write_snapshot(snapshot, path)
    args = build_parser().parse_args(["run", "--from", str(path)])
    folder = open_snapshot(args)
    try:
        assert args.allocator == "greedy" and args.seed == 0 and args.duration == pytest.approx(30.0)
        assert snapshot_options(args)["incarnations"] == (("arm_0", 2),)
    finally:
        folder.cleanup()


def test_a_scene_given_with_from_is_taken_where_its_content_is_the_snapshot_s(snapshot, tmp_path):
    """The bundled name, or the same file by absolute path, or a copy under another name: the same scene."""
    from fleet.cli import build_parser
    from fleet.cli.run_snapshots import open_snapshot

    copy = tmp_path / "my_cell.yaml"
    copy.write_text(resolve_scene_path("pick_cell").read_text())
    for given in ("pick_cell", str(resolve_scene_path("pick_cell").resolve()), str(copy)):
        args = build_parser().parse_args(["run", given, "--from", snapshot])
        open_snapshot(args).cleanup()
        assert args.seed == 0, given
