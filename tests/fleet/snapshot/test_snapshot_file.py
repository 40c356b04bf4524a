"""The snapshot file: written whole, read back equal, and every kind of bad file refused in one line before any
process's state is read (a truncated, corrupted, other-version or other-protocol file, one that is no snapshot)."""

from __future__ import annotations

import struct
import subprocess
import sys
import zlib
from pathlib import Path

import msgspec
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fleet.bus.messages import PROTOCOL_VERSION
from fleet.snapshot.snapshot_file import (
    FORMAT_VERSION,
    MAGIC,
    RunSnapshot,
    SceneSource,
    SnapshotError,
    node_state,
    read_snapshot,
    write_snapshot,
)

EXAMPLES = Path(__file__).parents[3] / "examples"


def a_snapshot(**changes) -> RunSnapshot:
    fields = {
        "scene_name": "pick_cell",
        "scene": SceneSource.of("pick_cell", None, 3),
        "mode": "lockstep",
        "tick": 900,
        "sim_time_s": 9.0,
        "end_tick": 3000,
        "allocator": "greedy",
        "states": {n: zlib.compress(bytes([i]) * 100) for i, n in enumerate(("sim", "coordinator", "arm_0"))},
    }
    return RunSnapshot(**(fields | changes))


def test_a_snapshot_reads_back_as_written(tmp_path):
    snapshot = a_snapshot()
    size = write_snapshot(snapshot, tmp_path / "s.clawsnap")
    assert size == (tmp_path / "s.clawsnap").stat().st_size
    assert read_snapshot(tmp_path / "s.clawsnap") == snapshot
    assert snapshot.arms == ["arm_0"]
    assert node_state(tmp_path / "s.clawsnap", "arm_0")[1] == b"\x02" * 100, "as its process wrote it"
    assert not list(tmp_path.glob("*.tmp")), "written whole, then renamed"


def test_a_missing_node_names_the_nodes_there(tmp_path):
    write_snapshot(a_snapshot(), tmp_path / "s.clawsnap")
    with pytest.raises(SnapshotError, match="no state for 'arm_7'; nodes: sim, coordinator, arm_0"):
        node_state(tmp_path / "s.clawsnap", "arm_7")


def _refusal(path: Path) -> str:
    with pytest.raises(SnapshotError) as refused:
        read_snapshot(path)
    message = str(refused.value)
    assert "\n" not in message and message.startswith(str(path))
    return message


def test_each_kind_of_bad_file_is_refused_in_one_line(tmp_path):
    good = tmp_path / "good.clawsnap"
    write_snapshot(a_snapshot(), good)
    data = good.read_bytes()
    bad = {
        "missing": None,
        "empty": b"",
        "not_a_snapshot": b"PK\x03\x04 a zip file" * 10,
        "truncated": data[: len(data) // 2],
        "corrupted": data[:-20] + bytes(b ^ 0xFF for b in data[-20:]),
        "other_format": data[:8] + struct.pack("<I", 99) + data[12:],
    }
    said = {}
    for name, content in bad.items():
        path = tmp_path / f"{name}.clawsnap"
        if content is not None:
            path.write_bytes(content)
        said[name] = _refusal(path)
    assert "no such snapshot file" in said["missing"]
    assert "not a clawfleet snapshot" in said["empty"] and "not a clawfleet snapshot" in said["not_a_snapshot"]
    assert "truncated or corrupted" in said["truncated"] and "truncated or corrupted" in said["corrupted"]
    assert "snapshot format 99" in said["other_format"]


def test_a_snapshot_of_another_bus_protocol_or_without_the_sim_is_refused(tmp_path):
    write_snapshot(a_snapshot(protocol_version=PROTOCOL_VERSION - 1), tmp_path / "old.clawsnap")
    assert f"bus protocol {PROTOCOL_VERSION - 1}" in _refusal(tmp_path / "old.clawsnap")
    write_snapshot(a_snapshot(states={"coordinator": b""}), tmp_path / "nosim.clawsnap")
    assert "no state for sim" in _refusal(tmp_path / "nosim.clawsnap")


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_any_damage_to_a_file_is_a_snapshot_error_never_another(tmp_path, data):
    path = tmp_path / "s.clawsnap"
    write_snapshot(a_snapshot(), path)
    raw = bytearray(path.read_bytes())
    cut = data.draw(st.integers(0, len(raw)))
    flips = data.draw(st.lists(st.tuples(st.integers(0, len(raw) - 1), st.integers(1, 255)), max_size=4))
    for at, mask in flips:
        raw[at] ^= mask
    path.write_bytes(bytes(raw[:cut]) if data.draw(st.booleans()) else bytes(raw))
    try:
        read_snapshot(path)
    except SnapshotError:
        pass


def test_the_body_is_decoded_only_as_a_snapshot(tmp_path):
    """A well-formed file whose body is some other MessagePack is refused, not half-read."""
    import hashlib

    body = zlib.compress(msgspec.msgpack.encode({"hello": "world"}))
    path = tmp_path / "other.clawsnap"
    path.write_bytes(MAGIC + struct.pack("<I", FORMAT_VERSION) + hashlib.sha256(body).digest() + body)
    assert "unreadable snapshot body" in _refusal(path)


def test_a_scene_source_stands_alone_with_its_robot_files_and_their_urdfs(tmp_path):
    """A scene whose robot is declared in a file (its URDF named relative to it) loads from the folder the snapshot
    writes, far from where the files were (in a process of its own: this one may hold the example's robot)."""
    example = EXAMPLES / "robots" / "my_claw_line.yaml"
    source = SceneSource.of(str(example), None, 4)
    assert sorted(source.files) == ["robot_0_my_claw.yaml", "robot_0_openclaw.urdf"]
    scene_file = source.write(tmp_path / "out")
    dump = (
        "import sys; from fleet.common.scene_loading import load_checked_scene; "
        "print(load_checked_scene(sys.argv[1], seed=4).model_dump_json(exclude={'robot_files'}))"
    )
    loaded = [
        subprocess.run([sys.executable, "-c", dump, str(f)], capture_output=True, text=True, check=True).stdout
        for f in (scene_file, example)
    ]
    assert loaded[0] == loaded[1] and "my_claw" in loaded[0]


def test_a_file_name_that_would_leave_the_folder_is_refused(tmp_path):
    source = SceneSource("s.yaml", "name: s\n", {"../../evil.yaml": "x"}, None, None)
    with pytest.raises(SnapshotError, match="not a plain file name"):
        source.write(tmp_path / "out")
    assert not (tmp_path.parent / "evil.yaml").exists()


def test_a_damaged_state_inside_a_sound_file_is_refused_for_its_node(tmp_path):
    write_snapshot(a_snapshot(states={"sim": b"not zlib", "coordinator": zlib.compress(b"x")}), tmp_path / "s.clawsnap")
    assert node_state(tmp_path / "s.clawsnap", "coordinator")[1] == b"x"
    with pytest.raises(SnapshotError, match="the state of sim is damaged"):
        node_state(tmp_path / "s.clawsnap", "sim")
