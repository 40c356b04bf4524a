"""Whatever JSON a client sends the rosbridge server, it answers with a `status` (or the op's own answer) and keeps
the connection: never an internal-error close (1011). Over a real websocket on loopback, the line's bus left out
(its actions go nowhere)."""

from __future__ import annotations

import asyncio
import json
import threading

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from websockets.sync.client import connect

from fleet.common.scene_loading import load_checked_scene
from fleet.ros import names
from fleet.ros.line_services import LineBus
from fleet.ros.rosbridge_server import RosbridgeServer

OPS = ["subscribe", "unsubscribe", "publish", "call_service", "send_action_goal", "cancel_action_goal", "advertise"]
TOPICS = ["/joint_states", "/arm_0/joint_trajectory", "/estop", "/arm_0/follow_joint_trajectory", "/nope"]

json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=20,
)
requests = st.fixed_dictionaries(
    {"op": st.sampled_from(OPS) | json_values},
    optional={
        "id": json_values,
        "topic": st.sampled_from(TOPICS) | json_values,
        "service": st.sampled_from([names.ESTOP, "/rosapi/topics", "/rosapi/nodes"]) | json_values,
        "action": st.sampled_from(TOPICS) | json_values,
        "args": json_values,
        "msg": json_values,
        "throttle_rate": json_values,
        "queue_length": json_values,
        "compression": st.sampled_from(["none", "cbor", "cbor-raw", "png"]) | json_values,
    },
)


@pytest.fixture(scope="module")
def port():
    """A rosbridge server of a two-arm sorting line on a free loopback port, served from a thread."""
    sent: list = []
    server = RosbridgeServer(load_checked_scene("sorting_line", arms=2), LineBus(sent.append, sent.append, sent.append))
    listening, stopping = threading.Event(), threading.Event()
    where: list[int] = []

    def listen(p: int) -> None:
        where.append(p)
        listening.set()

    thread = threading.Thread(
        target=lambda: asyncio.run(server.serve("127.0.0.1", 0, stopping.is_set, listen)), daemon=True
    )
    thread.start()
    assert listening.wait(10)
    yield where[0]
    stopping.set()
    thread.join(5)
    assert server.requests_failed == 0, "every request was refused by a check, none raised"


def answer(port: int, text: str) -> dict:
    with connect(f"ws://127.0.0.1:{port}") as ws:
        ws.send(text)
        return json.loads(ws.recv(timeout=5))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(request=requests)
def test_any_request_is_answered_and_the_connection_stays(port, request):
    with connect(f"ws://127.0.0.1:{port}") as ws:
        ws.send(json.dumps(request))
        ws.send(json.dumps({"op": "call_service", "service": "/rosapi/nodes", "id": "alive"}))
        replies = []
        while not any(r.get("id") == "alive" for r in replies):  # the connection outlived the request
            replies.append(json.loads(ws.recv(timeout=5)))


@pytest.mark.parametrize("depth", [65, 5000, 100_000])
def test_json_nested_deeper_than_the_server_reads_is_a_status_error(port, depth):
    reply = answer(port, "[" * depth + "]" * depth)
    assert reply["op"] == "status" and reply["level"] == "error" and "nested too deeply" in reply["msg"], reply
    deep_args = json.dumps({"op": "call_service", "service": names.ESTOP, "id": "d", "args": {"data": [[[[]]]]}})
    assert answer(port, deep_args)["op"] in ("status", "service_response")
