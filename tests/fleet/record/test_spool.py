"""The bus spool: the sim's own session hears every message of the run (its own, and those it routes between two
clients) and appends them to a file that a reader follows while it grows; a damaged or foreign spool is one line."""

import subprocess
import sys
import time

import msgspec
import pytest

from fleet.bus.keys import Keys
from fleet.bus.session import BusEndpoints, Inbox, open_listening_session, open_session
from fleet.common.scene_loading import load_checked_scene
from fleet.record.spool import BusSpool, SpoolError, SpoolReader, SpoolWriter

KEYS = Keys("spooltest")


def test_a_reader_follows_the_file_while_it_grows_and_knows_when_it_is_whole(tmp_path):
    written = tmp_path / "written.spool"
    writer = SpoolWriter(written, "spooltest", '{"name": "x"}')
    messages = [(f"clawfleet/spooltest/arm/arm_0/{i}", bytes([i]) * i) for i in range(40)]
    writer.write(messages)
    writer.close()
    whole = written.read_bytes()
    growing = tmp_path / "growing.spool"
    growing.write_bytes(b"")
    reader = SpoolReader(growing)
    heard = []
    for cut in range(0, len(whole), 7):  # the file grows 7 bytes at a time: frames are cut anywhere
        with open(growing, "ab") as f:
            f.write(whole[cut : cut + 7])
        if reader.header is None:
            reader.wait_for_header(0.0)
        else:
            heard += reader.drain()
        assert not reader.ended or cut + 7 >= len(whole)
    heard += reader.drain()
    assert (reader.header.run_id, reader.header.scene_json) == ("spooltest", '{"name": "x"}')
    assert heard == messages and reader.ended
    assert reader.drain() == []
    reader.close()


def test_a_spool_that_is_not_one_or_of_another_version_is_one_line(tmp_path):
    foreign = tmp_path / "foreign.spool"
    foreign.write_bytes(b"\x04\x00\x00\x00abcd")
    with pytest.raises(SpoolError, match="not a bus spool"):
        SpoolReader(foreign).wait_for_header(1.0)
    newer = tmp_path / "newer.spool"
    body = msgspec.msgpack.encode({"version": 99, "run_id": "r", "scene_json": "{}"})
    newer.write_bytes(len(body).to_bytes(4, "little") + body)
    with pytest.raises(SpoolError, match="spool version 99"):
        SpoolReader(newer).wait_for_header(1.0)
    assert SpoolReader(tmp_path / "none.spool").wait_for_header(0.1) is None


def test_the_routers_spool_hears_its_own_messages_and_those_it_routes_between_clients(tmp_path):
    router, endpoint = open_listening_session(BusEndpoints())
    path = tmp_path / "bus.spool"
    with router:
        spool = BusSpool(router, KEYS.recorded(), path, KEYS.run, "{}")
        with (
            open_session(BusEndpoints(connect=(endpoint,))) as coordinator,
            open_session(BusEndpoints(connect=(endpoint,))) as controller,
        ):
            heard = Inbox()
            sub = controller.declare_subscriber(KEYS.arm_step("arm_0"), heard)
            time.sleep(0.5)  # the subscriptions reach the router
            router.put(KEYS.frame, b"frame 1")
            for i in range(3):
                coordinator.put(KEYS.arm_step("arm_0"), f"step {i}".encode())
            router.put(KEYS.view, b"not recorded: the monitors' copy")
            deadline = time.monotonic() + 5.0
            while len(heard.drain()) < 3 and time.monotonic() < deadline:
                time.sleep(0.05)
            time.sleep(0.2)
            sub.undeclare()
        spool.close()
    reader = SpoolReader(path)
    reader.wait_for_header(1.0)
    messages = reader.drain()
    assert reader.ended
    assert messages == [(KEYS.frame, b"frame 1"), *[(KEYS.arm_step("arm_0"), f"step {i}".encode()) for i in range(3)]]


def test_the_recorder_gives_one_line_when_the_sim_wrote_no_spool(tmp_path):
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "fleet.nodes.recorder_node",
            "--spool",
            str(tmp_path / "missing.spool"),
            "--scene-timeout",
            "0.5",
            "--out",
            str(tmp_path / "out.mcap"),
            "--nice",
            "0",
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 1
    assert result.stderr.strip().splitlines() == [
        f"fleet record: the sim wrote no spool to {tmp_path / 'missing.spool'} within 0.5 s"
    ]
    assert not (tmp_path / "out.mcap").exists()


def test_a_spooled_scene_whose_robot_file_is_not_here_is_one_line(tmp_path):
    scene = load_checked_scene("assembly_line").model_copy(update={"robot_files": [str(tmp_path / "elsewhere.yaml")]})
    SpoolWriter(tmp_path / "bus.spool", "far", scene.model_dump_json()).close()
    result = subprocess.run(
        [
            sys.executable,
            "-m",
            "fleet.nodes.recorder_node",
            "--spool",
            str(tmp_path / "bus.spool"),
            "--out",
            str(tmp_path / "out.mcap"),
            "--nice",
            "0",
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 1
    (line,) = result.stderr.strip().splitlines()
    assert (
        line.startswith("fleet record: the scene of run 'far' names a robot file that cannot be used here:")
        and "elsewhere.yaml" in line
    )
