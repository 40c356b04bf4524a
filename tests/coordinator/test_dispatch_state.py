"""The dispatcher's saved state: put back into a fresh dispatcher of the same scene, it decides exactly as the one
it came from; a state that does not fit is refused naming the field."""

import msgspec
import numpy as np
import pytest

from coordinator.dispatch_state import DispatcherState, dispatcher_state, restore_dispatcher
from coordinator.dispatcher import Dispatcher
from coordinator.guard import TimedPath
from robots.saved_state import SavedStateError, pack, unpack
from tests.coordinator.test_dispatcher import HOME, PERIOD, SCENE, arrive, part_on_belt


def restored_copy(d: Dispatcher) -> Dispatcher:
    fresh = Dispatcher(SCENE)
    restore_dispatcher(fresh, unpack(pack(dispatcher_state(d)), DispatcherState))
    return fresh


def test_a_dispatcher_restored_mid_run_decides_exactly_as_the_one_saved():
    d = Dispatcher(SCENE)
    first = arrive(d)  # a task out, a belt deadline worked out
    d.arm_lost(first.arm, "no heartbeat", 0.8)  # a loss, its task back in the pool
    reach_out = tuple(HOME + [0.3, 0.4, -0.3, 0, 0.2, 0])
    request = TimedPath("arm_0", tuple(HOME), reach_out, 1.0, 2.0)
    copies, tick = [], 100
    for step in range(60):
        tick += PERIOD
        t = tick / SCENE.control_hz
        if step in (0, 5, 20):
            copies.append(restored_copy(d))
        for x in (d, *copies):
            x.on_parts({0: part_on_belt(x, 0, 0.4 + SCENE.conveyor.speed_m_per_s * (t - 1.0))}, t)
            if step == 10:
                x.on_arm("arm_0", HOME, "approach", t, request_seq=3, acts_at_tick=tick + 5, request=request)
        orders = d.decide(tick).orders
        assert all(c.decide(tick).orders == orders for c in copies)
        assert all(pack(dispatcher_state(c)) == pack(dispatcher_state(d)) for c in copies)
    assert d.decisions > 10 and d.grants.grants_given + d.guard.denied + d.guard.waits > 0, "a request was answered"
    assert d.report() == copies[0].report()


def test_a_state_with_a_renamed_field_is_refused_naming_it():
    saved = msgspec.msgpack.decode(pack(dispatcher_state(Dispatcher(SCENE))))
    saved["ledger"]["next_task"] = saved["ledger"].pop("next_task_id")
    with pytest.raises(SavedStateError, match=r"unknown field `next_task` - at `\$\.ledger`"):
        unpack(msgspec.msgpack.encode(saved), DispatcherState)
    assert np.isinf(unpack(pack(dispatcher_state(Dispatcher(SCENE))), DispatcherState).min_separation_m)
