"""Recording a real lockstep run (all processes) and reading the file back with the `mcap` reader and with
`rosbags`, as Foxglove and ROS 2 tools would: channels and schemas, counts, joint states, the TF tree, the
URDF; a second run of the same seed records the same messages; replay drives a subscriber with them."""

import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from mcap.reader import make_reader
from rosbags.highlevel import AnyReader

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState
from fleet.bus.session import BusEndpoints, Inbox, open_listening_session, open_session
from fleet.common.processes import StopFlag
from fleet.record import recorder as recorder_module
from fleet.record.mcap_file import Recording, RecordingWriter
from fleet.record.recorder import Recorder
from fleet.record.replay import Player
from fleet.record.report import series_from_recording, write_report
from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.in_process import fleet_in_process
from tests.fleet.record.tf_tree import up_to_root

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out

SECONDS = 12.0
ARMS = ("arm_0", "arm_1", "arm_2")
SIM_CLOCKED = (
    "state",
    "step",
    "goal",
    "result",
    "assign",
    "world/events",
    "world/frame",
    "world/parts",
    "coord/tick",
    "coord/separation",
)


def record_run(path: Path) -> dict:
    with Launcher(RunOptions(duration_s=SECONDS, record=str(path), seed=3)) as launcher:
        return launcher.run()


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rec")
    first, second = folder / "first.mcap", folder / "second.mcap"
    return record_run(first), first, record_run(second), second


def raw_payloads(path: Path, key: str) -> list[bytes]:
    return [m.payload for m in Recording(path).raw_messages([key])]


def without_resends(payloads: list[bytes]) -> list[bytes]:
    """A re-sent state or frame is the same bytes again, as often as the wall clock made the sim wait."""
    return [p for i, p in enumerate(payloads) if i == 0 or p != payloads[i - 1]]


def test_the_recording_finished_and_every_process_is_gone(recorded):
    summary, path, _, _ = recorded
    assert summary["status"] == "ok", summary["error"]
    assert summary["recording"]["file"] == str(path) and summary["recording"]["undecodable"] == 0
    assert {p["role"] for p in summary["processes"]} == {"sim", "coordinator", "controller", "recorder"}
    for p in summary["processes"]:
        with pytest.raises(ProcessLookupError):
            os.kill(p["pid"], 0)


def test_every_channel_is_there_with_its_ros_2_schema(recorded):
    _, path, _, _ = recorded
    with open(path, "rb") as f:
        reader = make_reader(f)
        header_profile = reader.get_header().profile
        summary = reader.get_summary()
    assert header_profile == "ros2"
    schemas = {s.id: s for s in summary.schemas.values()}
    channels = {c.topic: c for c in summary.channels.values()}
    expected = {
        "/tf": "tf2_msgs/msg/TFMessage",
        "/tf_static": "tf2_msgs/msg/TFMessage",
        "/cell": "visualization_msgs/msg/MarkerArray",
        "/parts": "visualization_msgs/msg/MarkerArray",
        "/line/events": "clawfleet_msgs/msg/LineEvent",
        "/line/summary": "std_msgs/msg/String",
        "/arm_0/trajectory_goals": "clawfleet_msgs/msg/TrajectoryGoalMsg",
        "/arm_0/goal_results": "clawfleet_msgs/msg/GoalResultMsg",
        "/arm_0/assignments": "clawfleet_msgs/msg/Assignment",
    }
    expected |= {f"/{a}/joint_states": "sensor_msgs/msg/JointState" for a in ARMS}
    expected |= {f"/{a}/robot_description": "std_msgs/msg/String" for a in ARMS}
    for topic, typename in expected.items():
        assert topic in channels, f"no {topic} in the recording"
        schema = schemas[channels[topic].schema_id]
        assert (schema.name, schema.encoding, channels[topic].message_encoding) == (typename, "ros2msg", "cdr")
    for latched in ("/tf_static", "/cell", "/line/summary", "/arm_0/robot_description"):
        assert "durability: 1" in channels[latched].metadata["offered_qos_profiles"], (
            f"{latched} is latched (transient local)"
        )
    assert "clawfleet/line/world/view" not in channels, "the monitors' copy of the frames is not recorded"
    for key in ("clawfleet/line/arm/arm_0/state", "clawfleet/line/world/frame", "clawfleet/line/coord/tick"):
        assert channels[key].message_encoding == "msgpack" and channels[key].schema_id == 0


def test_raw_counts_equal_what_the_sim_put_on_the_bus(recorded):
    summary, path, _, _ = recorded
    recording = Recording(path)
    sent = summary["bus_messages_out"]
    counted = {leaf: 0 for leaf in ("state", "result", "frame", "parts", "events", "status")}
    for key, n in recording.message_counts.items():
        if not key.startswith("clawfleet/"):
            continue
        leaf = key.rsplit("/", 1)[1]
        if leaf in counted and (leaf in ("state", "result") or "/world/" in key):
            counted[leaf] += n
    assert counted == {leaf: sent.get(leaf, 0) for leaf in counted}


def test_messages_come_in_sim_time_order_and_stamps_are_sim_time(recorded):
    _, path, _, _ = recorded
    recording = Recording(path)
    stamps = [m.stamp_ns for m in recording.raw_messages()]
    assert stamps == sorted(stamps)
    assert 0 <= recording.start_ns and recording.end_ns == pytest.approx(SECONDS * 1e9, abs=0.05e9)
    decoder = Decoder(ArmState, DropCounter())
    for m in recording.raw_messages(["clawfleet/line/arm/arm_1/state"]):
        assert m.stamp_ns == round(decoder.decode(m.key, m.payload).sim_time_s * 1e9)


def test_rosbags_reads_joint_states_equal_to_the_run_and_a_tf_tree_that_puts_each_tool_where_the_sim_did(recorded):
    _, path, _, _ = recorded
    recording = Recording(path)
    decoder = Decoder(ArmState, DropCounter())
    states = {a: {} for a in ARMS}
    for a in ARMS:
        for m in recording.raw_messages([Keys("line").arm_state(a)]):
            s = decoder.decode(m.key, m.payload)
            states[a].setdefault(s.tick, s)
    with AnyReader([path]) as reader:
        joints = {a: [] for a in ARMS}
        static, dynamic = {}, []
        for conn, stamp, data in reader.messages():
            if conn.topic.endswith("/joint_states"):
                joints[conn.topic.split("/")[1]].append((stamp, reader.deserialize(data, conn.msgtype)))
            elif conn.topic == "/tf_static":
                static |= {t.child_frame_id: t for t in reader.deserialize(data, conn.msgtype).transforms}
            elif conn.topic == "/tf":
                dynamic.append((stamp, reader.deserialize(data, conn.msgtype).transforms))
            elif conn.topic == "/line/events":
                event = reader.deserialize(data, conn.msgtype)  # a clawfleet_msgs type, from the file's own definition
                assert event.kind in ("arrived", "at_station", "lost", "retired")
    for a in ARMS:
        assert len(joints[a]) == len(states[a]) > 0.9 * SECONDS * 20
        for (stamp, js), s in zip(joints[a], states[a].values()):
            assert stamp == round(s.sim_time_s * 1e9)
            np.testing.assert_allclose(js.position, [*s.q, *s.gripper_q])

    assert len(dynamic) >= 0.9 * SECONDS * 10, "TF at the frames' 10 Hz"
    checked = 0
    for stamp, transforms in dynamic[:: max(1, len(dynamic) // 20)]:
        by_child = {t.child_frame_id: t for t in transforms} | static
        for arm in ARMS:
            root, world_from_tool = up_to_root(f"{arm}/tool_link", by_child)
            assert root == "world"
            state = next(s for s in states[arm].values() if round(s.sim_time_s * 1e9) == stamp)
            np.testing.assert_allclose(world_from_tool[:3, 3], state.tool_position, atol=2e-3)
            checked += 1
    assert checked >= 30


def test_each_arms_urdf_in_the_file_parses(recorded):
    _, path, _, _ = recorded
    recording = Recording(path)
    for a in ARMS:
        ((_, message, schema),) = recording.messages([f"/{a}/robot_description"])
        from fleet.record.ros_types import deserialize

        model = pin.buildModelFromXML(deserialize(message.data, schema).data)
        assert model.existFrame("tool_link") and model.nq == 8


def test_the_same_seed_records_the_same_messages(recorded):
    _, first, _, second = recorded
    a, b = Recording(first), Recording(second)
    sim_clocked = [k for k in a.raw_keys if any(k.endswith(leaf) for leaf in SIM_CLOCKED)]
    assert len(sim_clocked) >= 12
    for key in sim_clocked:
        assert without_resends(raw_payloads(first, key)) == without_resends(raw_payloads(second, key)), key
    for topic in ("/tf", "/arm_2/joint_states", "/parts", "/line/events"):
        ma = [(m.log_time, m.data) for _, m, _ in a.messages([topic])]
        mb = [(m.log_time, m.data) for _, m, _ in b.messages([topic])]
        assert ma == mb, topic


def rewrite(source: Path, out: Path, workers: int | None) -> None:
    """The source's raw messages recorded again: one at a time (`workers` None), or all at once by `workers`."""
    recording = Recording(source)
    heard = [(m.key, m.payload) for m in recording.raw_messages()]
    with RecordingWriter(out, recording.scene_json, recording.run_id) as writer:
        recorder = Recorder(writer, recording.scene, Keys(recording.run_id))
        if workers is None:
            for key, payload in heard:
                recorder.take(key, payload)
        else:
            recorder.take_all(heard, workers=workers)
        recorder.finish(None)


def test_a_forked_builder_writes_the_same_file_as_one_message_at_a_time(recorded, tmp_path, monkeypatch):
    _, first, _, _ = recorded
    monkeypatch.setattr(recorder_module, "PARALLEL_AT_LEAST", 1)  # a short run: fork even for a few messages
    one, forked = tmp_path / "one.mcap", tmp_path / "forked.mcap"
    rewrite(first, one, None)
    rewrite(first, forked, 2)
    assert one.read_bytes() == forked.read_bytes()
    again = Recording(forked)
    assert again.message_counts["/tf"] == Recording(first).message_counts["/tf"] > 50
    assert [m.data for _, m, _ in again.messages(["/tf"])] == [m.data for _, m, _ in Recording(first).messages(["/tf"])]


def test_replay_drives_a_subscriber_with_the_recorded_sequence(recorded):
    _, path, _, _ = recorded
    recording = Recording(path)
    keys = Keys("again")
    expected = raw_payloads(path, "clawfleet/line/arm/arm_0/state")
    session, endpoint = open_listening_session(BusEndpoints())
    with session, open_session(BusEndpoints(connect=(endpoint,))) as listener:
        inbox, views = Inbox(), Inbox()
        subs = [
            listener.declare_subscriber(keys.arm_state("arm_0"), inbox),
            listener.declare_subscriber(keys.view, views),
        ]
        time.sleep(0.5)  # the subscription reaches the player's session
        with Player(recording, session, keys, speed=20.0) as player:
            started = time.monotonic()
            player.run(StopFlag(watch_parent=False), until_end=True)
            took = time.monotonic() - started
        time.sleep(0.3)
        for sub in subs:
            sub.undeclare()
    assert [p for _, p in inbox.drain()] == expected
    assert len(views.drain()) == recording.message_counts["clawfleet/line/world/frame"], (
        "frames go out as the monitors' view too"
    )
    assert SECONDS / 20.0 * 0.8 < took < SECONDS / 20.0 + 3.0, f"paced by sim time at x20: {took:.2f} s"


def test_the_report_writes_series_and_plots(recorded, tmp_path):
    summary, path, _, _ = recorded
    series = series_from_recording(Recording(path))
    assert series.summary["parts_spawned"] == summary["parts_spawned"]
    assert {r["arm"] for r in series.arm_rows} == set(ARMS) and any(r["busy"] for r in series.arm_rows)
    assert len(series.line_rows) >= SECONDS * 10 * 0.9
    written = write_report(series, tmp_path)
    assert {p.name for p in written} == {"arms.csv", "line.csv", "gantt.png", "line.png", "round_trip.png"}
    for p in written:
        assert p.stat().st_size > 1000, p
    assert (tmp_path / "gantt.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_one_arm_line_still_gets_its_line_series_and_a_plot_without_warnings(tmp_path):
    path = tmp_path / "pick_cell.mcap"
    with Launcher(RunOptions(scene="pick_cell", duration_s=20.0, record=str(path), seed=0)) as launcher:
        summary = launcher.run()
    series = series_from_recording(Recording(path))
    assert series.line_rows, "a one-arm line has no separations: its rows come from the coordinator's progress"
    assert {r["closest_separation_m"] for r in series.line_rows} == {None}
    assert series.line_rows[-1]["parts_spawned"] <= summary["parts_spawned"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # matplotlib's "no artists with labels" legend warning among them
        write_report(series, tmp_path)
    assert len((tmp_path / "line.csv").read_text().splitlines()) == len(series.line_rows) + 1


@pytest.mark.parametrize("command", ["replay", "report"])
def test_a_truncated_or_foreign_file_is_one_line_and_exit_2(recorded, tmp_path, command):
    _, path, _, _ = recorded
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    foreign = tmp_path / "notes.mcap"
    foreign.write_text("not a recording\n")
    for bad, says in (
        (cut, "cut short or damaged"),
        (foreign, "not an MCAP file"),
        (tmp_path / "none.mcap", "no such recording"),
    ):
        extra = ["--out", str(tmp_path / "out")] if command == "report" else []
        code, _, stderr = fleet_in_process([command, str(bad), *extra])
        assert code == 2, stderr
        assert says in stderr and len(stderr.strip().splitlines()) == 1, stderr


def test_fleet_record_taps_a_line_already_running_and_finishes_the_file_on_ctrl_c(tmp_path):
    from fleet.bus.session import free_loopback_port, loopback_endpoint

    endpoint = loopback_endpoint(free_loopback_port())
    line = subprocess.Popen(
        [sys.executable, "-m", "fleet", "run", "--duration", "600", "--mode", "realtime", "--listen", endpoint],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    path = tmp_path / "tap.mcap"
    try:
        tap = subprocess.Popen(
            [sys.executable, "-m", "fleet", "record", "--connect", endpoint, "--wait", "60", str(path)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        deadline = time.monotonic() + 90
        while not (path.is_file() and path.stat().st_size > 20_000):
            assert time.monotonic() < deadline and tap.poll() is None, "the recorder wrote nothing"
            time.sleep(0.2)
        time.sleep(2.0)
        tap.send_signal(signal.SIGINT)
        _, err = tap.communicate(timeout=60)
        assert tap.returncode == 0, err[-2000:]
    finally:
        line.send_signal(signal.SIGINT)
        line.communicate(timeout=60)
    recording = Recording(path)
    assert recording.run_id == "line" and recording.scene.name == "assembly_line"
    assert recording.message_counts["/arm_0/joint_states"] > 20 and recording.message_counts["/tf"] > 10
    assert "/line/summary" not in recording.channels, "a tap has no run summary to add"
