"""Every message type survives a round trip; malformed, truncated and wrong-version payloads are dropped and counted."""

import re
from pathlib import Path

import msgspec
import pytest

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.messages import (
    MESSAGE_TYPES,
    PROTOCOL_VERSION,
    ArmState,
    ArmStatus,
    Assignment,
    CameraImage,
    ControllerStep,
    CoordTick,
    EnvAction,
    EnvTargets,
    EStop,
    GoalResultMsg,
    GripperGoalMsg,
    LineEvent,
    LineView,
    MotionGrant,
    PartDetections,
    PartsState,
    Progress,
    RespawnRequest,
    Roster,
    Separations,
    SimControl,
    SimStatus,
    SnapshotAsk,
    SnapshotPart,
    TrajectoryGoalMsg,
    wire_layout,
)

EXAMPLES = [
    ArmState("arm_0", 12, 0.12, (0.1,) * 6, (0.0,) * 6, (0.02, 0.02), (0.3, 0.1, 0.2), (1.0, 0.0, 0.0, 0.0), True),
    ArmState(
        "arm_1",
        13,
        0.13,
        (0.1,) * 6,
        (0.0,) * 6,
        (0.02, 0.02),
        (0.3, 0.1, 0.2),
        (1.0, 0.0, 0.0, 0.0),
        False,
        True,
        4,
        "lift",
        0.5,
        3,
    ),
    ArmState(
        "arm_1",
        15,
        0.15,
        (0.1,) * 6,
        (0.0,) * 6,
        (0.02, 0.02),
        (0.3, 0.1, 0.2),
        (1.0, 0.0, 0.0, 0.0),
        goal_id=7,
        desired_q=(0.11,) * 6,
        desired_dq=(0.01,) * 6,
        result_goal_id=6,
        result_status="preempted",
        next_tick=20,
        period_ticks=5,
    ),
    ControllerStep("arm_1", 12, 17),
    ControllerStep("arm_1", 12, 17, (41, 42), 4, "descend", 0.25),
    TrajectoryGoalMsg("arm_0", 41, ("a", "b"), (0.5, 1.0), (0.1, 0.2, 0.3, 0.4)),
    TrajectoryGoalMsg(
        "arm_0", 41, ("a", "b"), (0.5,), (0.1, 0.2), (0.0, 0.0), (0.0, 0.0), 3.25, (0.3,), (0.01, 0.02), 0.2
    ),
    GripperGoalMsg("arm_0", 42, 0.0, 20.0, 3.75),
    GoalResultMsg("arm_0", 41, "trajectory", "aborted", -4, "shoulder_lift 0.3 rad off its path", 4.5),
    GoalResultMsg("arm_0", 42, "gripper", "succeeded", 0, "", 4.9, False, True),
    ArmStatus("arm_2", 7, 3.5, "descend", 4, 0.25),
    ArmStatus("arm_2", 8, 3.6, "failed", 4, 0.25, 2.5, "the claw closed on nothing"),
    PartsState(
        3,
        0.03,
        (1, 2),
        ("bases", "tops"),
        (0, 0),
        (0.0,) * 6,
        (1.0, 0, 0, 0) * 2,
        (0.05, 0, 0) * 2,
        (0.05, 0.05, 0.03) * 2,
    ),
    Assignment("arm_0", 1, 9, 17, 0.08, (0.3, -0.5, 0.04), (0.05, 0.0, 0.0)),
    Assignment("arm_0", 2, None, 17, 0.08, (0.3, -0.5, 0.04), (0.0, 0.0, 0.0)),
    LineEvent("at_station", 17, 400, "fixture_0"),
    CoordTick(400, (3, 0, 1)),
    Progress(4.0, 3, 1, 0, 2),
    Progress(4.0, 3, 1, 0, 2, 1, 3, 0.08),
    EStop(True, "monitor"),
    SimControl("monitor", paused=True),
    SimControl("monitor", speed=2.0),
    SimControl("monitor", snapshot=True),
    SimStatus(300, 3.0, "lockstep", False, False, 1.0, (0.5, 0.25), 1.8, 0),
    SimStatus(300, 3.0, "realtime", True, True, 2.0, (0.5,), 1.8, 4, ("arm_0-arm_1",), 2.9, ("arm_1",), 3),
    Separations(3.0, ("arm_0",), ("arm_1",), (0.1,), (0.0, 0.0, 0.2, 0.1, 0.0, 0.2), 0.02),
    RespawnRequest("arm_1", "monitor"),
    Roster(("coordinator", "arm_0"), (2, 1)),
    MotionGrant("arm_0", 3, 2, "grant"),
    MotionGrant("arm_0", 5, 4, "grant", "", 0.3, 12.05),
    EnvAction("arm_0", 5, "act", (0.1, -1.0, 0.0, 1.0)),
    EnvTargets("arm_0", 5, (0.2,) * 6, 1.0),
    SnapshotAsk(900, "coordinator", events=12),
    SnapshotAsk(900, "controllers", orders=(3, 0, 5), parts_tick=895),
    SnapshotPart("coordinator", 900, b"\x80\x05state", orders=(3, 0, 5)),
    SnapshotPart("arm_0", 900, error="cannot snapshot ArmController (attributes x): no"),
    SnapshotPart("arm_0", 900, restored=True),
    MotionGrant("arm_0", 4, 3, "deny", "arm_1", 0.012),
    PartDetections(
        "overhead", 20, 0.2, (3, 4), (0, 1), (0.1, 0.3, 0.11, 0.2, 0.3, 0.11), (0.1, -0.3), (0.9, 0.6), (0.2, 0.0)
    ),
    CameraImage(
        "overhead", "rgb", 20, 0.2, 2, 1, "raw", b"\x01\x02\x03\x04\x05\x06", (1.0,) * 9, (0.0, 0.0, 1.0), (0.5,) * 4
    ),
    LineView(
        3,
        0.03,
        (ArmState("arm_0", 3, 0.03, (0.1,) * 6, (0.0,) * 6, (0.02, 0.02), (0.3, 0.1, 0.2), (1.0, 0.0, 0.0, 0.0)),),
        PartsState(3, 0.03, (1,), ("bases",), (0,), (0.0,) * 3, (1.0, 0, 0, 0), (0.05, 0, 0), (0.05, 0.05, 0.03)),
    ),
]


def test_the_protocol_doc_gives_every_messages_wire_layout():
    doc = (Path(__file__).parents[3] / "docs" / "protocol.md").read_text()
    missing = [wire_layout(t) for t in MESSAGE_TYPES if f"- {wire_layout(t)}" not in doc]
    assert not missing, "docs/protocol.md's wire layout is out of date:\n" + "\n".join(missing)


def test_the_protocol_doc_names_one_version_the_code_s():
    doc = (Path(__file__).parents[3] / "docs" / "protocol.md").read_text()
    named = re.findall(r"(?:protocol version|versions?)\W{0,6}(\d+)", doc, re.IGNORECASE)
    assert len(named) >= 2 and set(named) == {str(PROTOCOL_VERSION)}, named


def test_every_message_type_has_an_example():
    assert {type(m) for m in EXAMPLES} == set(MESSAGE_TYPES)


@pytest.mark.parametrize("message", EXAMPLES, ids=lambda m: type(m).__name__)
def test_round_trip(message):
    drops = DropCounter()
    decoded = Decoder(type(message), drops).decode("k", encode(message))
    assert decoded == message
    assert drops.total == 0


def test_arm_state_is_compact():
    """Field names stay off the wire: a realistic state is well under half its JSON size."""
    import numpy as np

    v = tuple(np.random.default_rng(0).uniform(-2, 2, 6).tolist())
    state = ArmState("arm_0", 123456, 1234.56, v, v, v[:2], v[:3], v[:4], False)
    assert len(encode(state)) < 0.5 * len(msgspec.json.encode(msgspec.structs.asdict(state)))


@pytest.mark.parametrize(
    "payload", [b"", b"\x00\x01garbage", b"\xff" * 40, encode(EXAMPLES[0])[:-5], encode(EStop(True, "x"))]
)
def test_malformed_payloads_are_dropped_and_counted(payload):
    drops = DropCounter()
    assert Decoder(ControllerStep, drops).decode("clawfleet/r/arm/arm_0/step", payload) is None
    assert drops.total == 1


def test_invalid_utf8_in_a_string_field_is_dropped():
    """msgspec raises UnicodeDecodeError (not a DecodeError) for this one; a bus must not crash on it."""
    payload = b"\x95\xa5arm_\xc3\x28\x01\x90\x90\xcb" + b"\x00" * 8
    drops = DropCounter()
    assert Decoder(ControllerStep, drops).decode("k", payload) is None
    assert drops.total == 1


def test_random_bytes_never_raise():
    import os

    drops = DropCounter()
    decoders = [Decoder(t, drops) for t in MESSAGE_TYPES]
    for _ in range(2000):
        payload = os.urandom(int.from_bytes(os.urandom(1), "little") % 64)
        for d in decoders:
            d.decode("k", payload)  # returns a message or None; never raises


def test_wrong_version_is_dropped():
    drops = DropCounter()
    old = msgspec.structs.replace(EXAMPLES[1], version=99)
    decoder = Decoder(ArmState, drops)
    assert decoder.decode("k", encode(old)) is None
    assert decoder.decode("k", encode(old)) is None
    assert drops.total == 2 and len(drops.counts) == 1


def test_orders_on_one_key_decode_to_their_own_type():
    from fleet.bus.messages import ArmOrder

    decoder = Decoder(ArmOrder, DropCounter())
    grant = MotionGrant("arm_0", 3, 2, "grant")
    assignment = Assignment("arm_0", 2, 9, 17, 0.08, (0.3, -0.5, 0.04), (0.05, 0.0, 0.0))
    assert decoder.decode("k", encode(grant)) == grant
    assert decoder.decode("k", encode(assignment)) == assignment
    assert decoder.decode("k", encode(Progress(4.0, 3, 1, 0, 2))) is None and decoder.drops.total == 1


def test_trajectory_and_gripper_goals_on_one_key_decode_to_their_own_type():
    from fleet.bus.messages import ArmGoalMsg

    decoder = Decoder(ArmGoalMsg, DropCounter())
    trajectory = TrajectoryGoalMsg("arm_0", 41, ("a",), (0.5,), (0.1,))
    gripper = GripperGoalMsg("arm_0", 42, 1.0)
    assert decoder.decode("k", encode(trajectory)) == trajectory
    assert decoder.decode("k", encode(gripper)) == gripper
    assert decoder.decode("k", encode(EStop(True, "x"))) is None and decoder.drops.total == 1
