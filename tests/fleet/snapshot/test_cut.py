"""Which messages a node holds back from a snapshot's tick on: told apart by the tick they carry (a state or frame by
the tick it reached the node, an order by its decision's tick, a heartbeat by its sim time), never by arrival order;
a message that cannot be read passes (the node's loop drops and counts it)."""

import msgspec
from hypothesis import given
from hypothesis import strategies as st

from fleet.bus.codec import encode
from fleet.bus.messages import ArmState, ArmStatus, Assignment, LineEvent, LineView, MotionGrant, PartsState, Roster
from fleet.snapshot.cut import Cut, controller_after_cut, coordinator_after_cut

HZ = 100.0
CUT = Cut(600)
coordinator_after = coordinator_after_cut(HZ)


def _state(tick: int, delivered: int = -1) -> ArmState:
    return ArmState(
        "arm_0",
        tick,
        tick / HZ,
        (0.0,),
        (0.0,),
        (0.0,),
        (0.0, 0.0, 0.0),
        (1.0, 0.0, 0.0, 0.0),
        delivered_tick=delivered,
    )


def _parts(tick: int) -> PartsState:
    return PartsState(tick, tick / HZ, (), (), (), (), (), (), ())


def test_a_controller_holds_states_parts_and_orders_from_the_cut_on():
    def held(leaf: str, msg) -> bool:
        return controller_after_cut(f"clawfleet/line/arm/arm_0/{leaf}", encode(msg), CUT)

    assert not held("state", _state(595)) and held("state", _state(600))
    assert held("state", _state(590, delivered=601)), "a delayed state reaching the node after the cut"
    assert not held("parts", _parts(599)) and held("parts", _parts(600))
    order = Assignment("arm_0", 7, 3, 12, 0.1, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), decision_tick=590)
    assert not held("assign", order)
    assert held("assign", Assignment("arm_0", 8, 3, 12, 0.1, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), decision_tick=600))
    assert held("assign", MotionGrant("arm_0", 9, 2, "grant", decision_tick=610))
    assert not held("roster", Roster(("sim", "arm_0"), (1, 1)))


def test_the_coordinator_holds_frames_events_and_heartbeats_from_the_cut_on():
    def held(leaf: str, msg) -> bool:
        return coordinator_after(f"clawfleet/line/{leaf}", encode(msg), CUT)

    frame = LineView(590, 5.9, (_state(590),), _parts(590))
    assert not held("world/frame", frame)
    assert held("world/frame", LineView(600, 6.0, (_state(600),), _parts(600)))
    assert held("world/frame", LineView(590, 5.9, (_state(590),), _parts(590), delivered_tick=602))
    assert not held("world/events", LineEvent("arrived", 4, 599, "belt")) and held(
        "world/events", LineEvent("lost", 4, 600, "")
    )
    status = ArmStatus("arm_0", 3, 5.95, "idle", None, 0.0)
    assert not held("arm/arm_0/status", status)
    assert held("arm/arm_0/status", ArmStatus("arm_0", 4, 6.0, "idle", None, 0.0))


TYPES = {"state": ArmState, "parts": PartsState, "assign": Assignment | MotionGrant, "events": LineEvent}
TYPES |= {"frame": LineView, "status": ArmStatus, "roster": Roster}


@given(st.binary(max_size=200), st.sampled_from(sorted(TYPES)))
def test_a_message_that_cannot_be_read_is_never_held_and_never_raises(payload, leaf):
    try:
        msgspec.msgpack.decode(payload, type=TYPES[leaf])
    except (msgspec.MsgspecError, UnicodeDecodeError, ValueError, OverflowError):
        assert controller_after_cut(f"k/{leaf}", payload, CUT) is False
        assert coordinator_after(f"k/{leaf}", payload, CUT) is False
