"""The sim's saved state, piece by piece: each component put back goes on as the one saved; bytes that are not a
sim's state are refused in one line, naming what is wrong."""

import msgspec
import numpy as np
import pytest

from fleet.bus.faults import FaultyLink
from fleet.bus.flights import BookState, FlightBook
from fleet.bus.messages import ArmState, ControllerStep
from fleet.sim.sim_state import SimState, read_sim_state
from fleet.sim.sim_stats import SimStats, StatsState
from fleet.snapshot.process_state import StateError
from robots.saved_state import SavedStateError, generator_of, generator_state, pack, unpack
from scenes.schema import LinkFaults


def faulty_link() -> FaultyLink:
    return FaultyLink("arm_0", LinkFaults(latency_ms=20.0, jitter_ms=10.0, loss=0.2), seed=3, index=0)


def test_a_link_s_faults_put_back_draw_the_same_fates_from_there_on():
    saved = faulty_link()
    for _ in range(17):
        saved.passage("down"), saved.passage("up")
    restored = faulty_link()
    restored.restore(unpack(pack(saved.state()), type(saved.state())))
    assert [restored.passage(d) for d in ("down", "up") * 50] == [saved.passage(d) for d in ("down", "up") * 50]
    assert restored.report() == saved.report()


def test_a_flight_book_put_back_delivers_and_applies_as_the_one_saved():
    link = FaultyLink("arm_0", LinkFaults(), seed=0, index=0)
    saved = FlightBook(link, 100.0)
    state = ArmState("arm_0", 4, 0.04, (0.0,) * 6, (0.0,) * 6, (0.0, 0.0), (0.3, 0.0, 0.2), (1.0, 0.0, 0.0, 0.0))
    saved.send(4, state, 5, 0.0, lockstep=True)
    saved.deliver(4, 0.0, lockstep=True)
    saved.answer(4, ControllerStep("arm_0", 4, 9, (11,), 2))
    restored = FlightBook(link, 100.0)
    restored.restore(unpack(pack(saved.state()), BookState[ArmState, ControllerStep]))
    assert [f.answer for f in restored.due_answers(9)] == [f.answer for f in saved.due_answers(9)]


def test_counts_put_back_are_the_counts_saved():
    saved = SimStats()
    saved.results["succeeded"] += 3
    saved.contacts({("arm_0", "arm_1")}, 1.5)
    for ms in (0.5, 2.0, 40.0):
        saved.round_trip(ms)
    restored = SimStats()
    restored.restore(unpack(pack(saved.state()), StatsState))
    assert restored == saved


def test_a_generator_put_back_draws_what_the_saved_one_would():
    rng = np.random.default_rng([7, 0xFA017])
    rng.normal(size=13)
    again = generator_of(generator_state(rng))
    assert np.array_equal(again.normal(size=50), rng.normal(size=50))
    with pytest.raises(SavedStateError, match="not a saved random generator"):
        generator_of('{"bit_generator": "os.system"}')


def test_bytes_that_are_not_a_sim_s_state_are_refused_in_one_line_naming_the_field():
    with pytest.raises(StateError, match="cannot read back the state of the sim") as not_one:
        read_sim_state(b"\x93not a state")
    assert "\n" not in str(not_one.value)
    fields = {f: None for f in SimState.__struct_fields__}
    with pytest.raises(StateError, match=r"\$\.world"):
        read_sim_state(msgspec.msgpack.encode({**fields, "version": 1}))


def test_messages_on_their_way_in_are_held_again_as_they_were():

    from fleet.bus.flights import Flight
    from fleet.bus.lockstep import ArmLink
    from fleet.bus.messages import CoordTick, GripperGoalMsg
    from fleet.sim.sim_inputs import InputsState, SimInputs

    def realtime_inputs() -> SimInputs:
        link = ArmLink("arm_0", 5, FlightBook(FaultyLink("arm_0", LinkFaults(), seed=0, index=0), 100.0))
        return SimInputs(*(None,) * 4, {"arm_0": link}, *(None,) * 4, assign_seqs={}, watchdog_s=0.25)  # state only

    saved = realtime_inputs()
    link = saved.links["arm_0"]
    answer = ControllerStep("arm_0", 4, 9, (11,), 2)
    saved.delayed.push(3.5, ("coord", None, CoordTick(12, (1,))))
    saved.delayed.push(3.2, ("goal", link, GripperGoalMsg("arm_0", 11, 0.4)))
    state = ArmState("arm_0", 4, 0.04, (0.0,) * 6, (0.0,) * 6, (0.0, 0.0), (0.3, 0.0, 0.2), (1.0, 0.0, 0.0, 0.0))
    saved.delayed.push(3.9, ("step", link, Flight(4, state, 4, 3.0, 9, False, True, b"s", answer, 3.0)))
    saved.outside_goals.add(11)
    restored = realtime_inputs()
    restored.restore(unpack(pack(saved.state()), InputsState))
    assert restored.outside_goals == {11} and restored.delayed.count == 3
    again = restored.delayed.pop_due(10.0)
    assert [(kind, None if at is None else at.name, item) for kind, at, item in again] == [
        (kind, None if at is None else at.name, item) for kind, at, item in saved.delayed.pop_due(10.0)
    ]
    assert again[0][1] is restored.links["arm_0"], "held for the restored sim's own link"
