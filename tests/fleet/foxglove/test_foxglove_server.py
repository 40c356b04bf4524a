"""The line's Foxglove server, checked with Foxglove's own reference client (`@foxglove/ws-protocol`, run with node
from tests/clients): the line's topics advertised as ROS 2 messages with their definitions, the messages that
arrive decoded by `rosbags` (a reader clawfleet did not write) and logged at sim time, the server's time the line's,
the status as JSON, and a pause asked for as a service reaching the line."""

import base64
import json
import subprocess
import sys
from pathlib import Path

import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from rosbags.typesys import Stores, get_typestore

from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.in_process import fleet_in_process
from tests.fleet.line_beside import run_beside

CLIENTS = Path(__file__).resolve().parents[2] / "clients"
TOPICS = "/joint_states:3,/tf:2,/tf_static:1,/cell:1,/parts:1,/clock:2,/line/status:2,/scene/cell:1,/scene/parts:2"
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)


def reference_client(url: str, topics: str, *service: str) -> subprocess.CompletedProcess:
    if not (CLIENTS / "node_modules" / "@foxglove" / "ws-protocol").is_dir():
        pytest.fail("Foxglove's client is missing: npm ci --prefix tests/clients (scripts/install-system-packages)")
    script = str(CLIENTS / "foxglove_client.js")
    return subprocess.run(["node", script, url, topics, *service], capture_output=True, text=True, timeout=60)


@pytest.fixture(scope="module")
def watched() -> tuple[dict, dict]:
    """A realtime pick_cell line served to Foxglove; what the reference client saw (it pauses the line at the
    end), and the run's summary."""

    def user(launcher: Launcher, seen: dict) -> None:
        done = reference_client(launcher.server_url("foxglove"), TOPICS, "/pause", "{}")
        seen.update(rc=done.returncode, stderr=done.stderr[-2000:], **json.loads(done.stdout or "{}"))

    options = RunOptions(scene="pick_cell", duration_s=120.0, mode="realtime", foxglove_port=0)
    summary, seen, _ = run_beside(options, user)
    assert "error" not in seen and seen["rc"] == 0, seen
    return seen, summary


pytestmark = pytest.mark.slow  # a whole realtime line and a node process


def messages(seen: dict, topic: str, typename: str) -> list:
    return [TYPESTORE.deserialize_cdr(base64.b64decode(m["data"]), typename) for m in seen["messages"][topic]]


def test_the_reference_client_is_offered_the_line_s_topics_as_ros2_messages_with_their_definitions(watched):
    seen, _ = watched
    assert seen["serverInfo"]["name"] == "clawfleet" and set(seen["serverInfo"]["capabilities"]) >= {"time", "services"}
    channels = {c["topic"]: c for c in seen["channels"]}
    for topic, typename in (("/joint_states", "sensor_msgs/msg/JointState"), ("/tf", "tf2_msgs/msg/TFMessage")):
        assert channels[topic]["encoding"] == "cdr" and channels[topic]["schemaName"] == typename
        assert channels[topic]["schemaEncoding"] == "ros2msg"
    assert "MSG: geometry_msgs/Transform" in channels["/tf"]["schema"], "every type inside it, as Foxglove decodes by"
    assert {"/overhead/image_raw/compressed", "/overhead/camera_info", "/rosout"} <= set(channels)
    assert channels["/line/status"]["encoding"] == "json"


def test_its_messages_decode_with_rosbags_and_are_logged_at_sim_time(watched):
    seen, _ = watched
    joints = messages(seen, "/joint_states", "sensor_msgs/msg/JointState")
    assert all(n.startswith("arm_0/") for n in joints[-1].name) and len(joints[-1].position) == len(joints[-1].name)
    frames = {t.child_frame_id for m in messages(seen, "/tf", "tf2_msgs/msg/TFMessage") for t in m.transforms}
    assert any(f.startswith("arm_0/") for f in frames)
    static = messages(seen, "/tf_static", "tf2_msgs/msg/TFMessage")[0]
    assert any(t.header.frame_id == "world" for t in static.transforms), "the arms' roots on the world"
    clock = messages(seen, "/clock", "rosgraph_msgs/msg/Clock")
    stamps = [c.clock.sec * 10**9 + c.clock.nanosec for c in clock]
    assert stamps == sorted(stamps) and [int(m["logTime"]) for m in seen["messages"]["/clock"]] == stamps
    times = [int(t) for t in seen["times"]]
    assert times == sorted(times) and 0 < times[-1] < 120 * 10**9, "the server's time is the line's sim time"


def protobuf_messages(seen: dict, topic: str) -> list:
    """A protobuf channel's messages, decoded by Google's protobuf runtime from the schema the server advertised
    (a FileDescriptorSet), as the app decodes them."""
    channel = next(c for c in seen["channels"] if c["topic"] == topic)
    assert channel["encoding"] == "protobuf" and channel["schemaEncoding"] == "protobuf"
    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"])).file:
        pool.Add(file)
    kind = message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))
    return [kind.FromString(base64.b64decode(m["data"])) for m in seen["messages"][topic]]


def test_the_cell_and_the_parts_are_scene_entities_of_foxglove_s_own_schema(watched):
    seen, _ = watched
    cell = protobuf_messages(seen, "/scene/cell")[0]
    ids = {e.id for e in cell.entities}
    assert "belt/0" in ids and any(i.startswith("stations/") for i in ids), ids
    assert all(e.frame_id == "world" and len(e.cubes) == 1 and e.cubes[0].size.x > 0 for e in cell.entities)
    parts = protobuf_messages(seen, "/scene/parts")
    assert all(len(u.deletions) == 1 for u in parts), "each update replaces the last"
    shown = [e for u in parts for e in u.entities]
    assert all(e.id.startswith("parts/") and (e.cubes or e.cylinders) for e in shown)


def test_the_status_plots_and_a_pause_from_the_app_reaches_the_line(watched):
    seen, _ = watched
    status = [json.loads(base64.b64decode(m["data"])) for m in seen["messages"]["/line/status"]]
    assert status[-1]["mode"] == "realtime" and status[-1]["sim_time_s"] > 0 and len(status[-1]["utilisation"]) == 1
    assert set(seen["services"]) == {"/estop", "/pause", "/resume"}
    assert seen["serviceAnswer"] == {"success": True, "message": "paused"}


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["foxglove"], "needs --connect ENDPOINT or --zenoh-config FILE"),
        (["foxglove", "--connect", "tcp/127.0.0.1:1", "--port", "70000"], "--port 70000"),
    ],
)
def test_fleet_foxglove_refuses_what_cannot_work_in_one_line(argv, said):
    code, _, stderr = fleet_in_process(argv)
    assert code == 2 and said in stderr and stderr.strip().count("\n") == 0, stderr


def test_the_server_refuses_to_listen_beyond_loopback():
    from fleet.nodes import foxglove_node

    assert foxglove_node.main(["--host", "0.0.0.0", "--connect", "tcp/127.0.0.1:1"]) == 2


@pytest.fixture(scope="module")
def replayed(tmp_path_factory) -> dict:
    """A 12 s lockstep pick_cell recording, replayed to Foxglove (`fleet replay --foxglove`); what the reference
    client saw as it played at twice real time for 3 s of the line, then sought back to 1.5 s."""
    path = tmp_path_factory.mktemp("replay") / "line.mcap"
    with Launcher(RunOptions(scene="pick_cell", duration_s=12.0, seed=0, record=str(path))) as launcher:
        assert launcher.run()["status"] == "ok"
    argv = [sys.executable, "-m", "fleet", "replay", str(path), "--foxglove", "--foxglove-port", "0"]
    replay = subprocess.Popen(argv + ["--run-id", "replayed"], stderr=subprocess.PIPE, text=True)
    try:
        said = ""
        while "foxglove: ws://" not in said and replay.poll() is None:
            said = replay.stderr.readline()
        assert "foxglove: ws://" in said, said
        script = str(CLIENTS / "foxglove_playback.js")
        url = said.split("foxglove: ", 1)[1].strip()
        play = ["node", script, url, "2.0", "25", "1.5", "5"]  # at 2x; 25 clocks, back to 1.5 s, 5 more
        done = subprocess.run(play, capture_output=True, text=True, timeout=60)
    finally:
        replay.send_signal(2)  # Ctrl-C ends a replay
        replay.wait(30)
    assert done.returncode == 0, (done.stdout, done.stderr)
    return json.loads(done.stdout) | {"replay_exit": replay.returncode}


def clock_ns(encoded: str) -> int:
    clock = TYPESTORE.deserialize_cdr(base64.b64decode(encoded), "rosgraph_msgs/msg/Clock").clock
    return clock.sec * 10**9 + clock.nanosec


def test_a_replay_plays_from_foxglove_s_timeline_and_a_seek_back_lands_where_it_was_asked(replayed):
    assert "playbackControl" in replayed["serverInfo"]["capabilities"] and replayed["errors"] == []
    before, after = [clock_ns(c) for c in replayed["before"]], [clock_ns(c) for c in replayed["after"]]
    assert before == sorted(before) and before[-1] >= 2.4e9, "it played forward"
    seek = next(s for s in replayed["states"] if s["requestId"] == "seek-back")
    assert seek["didSeek"] and int(seek["currentTime"]) == 1_500_000_000 and seek["status"] == 0  # playing
    assert 1.5e9 <= after[0] < 2.5e9 and after == sorted(after), "the line as it was from 1.5 s on"
    assert replayed["replay_exit"] == 130, "Ctrl-C ended the replay"
