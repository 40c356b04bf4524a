"""The coordinator applies the line's events at the decision whose tick reaches them. A lockstep sim runs on to the
next decision while one is made; an event of a later tick that reaches the coordinator first must not change it
(it did, now and then, on a loaded machine: the same seed gave 19 parts in one run and 21 in another)."""

import time

from fleet.bus.codec import encode
from fleet.bus.keys import Keys
from fleet.bus.messages import LineEvent
from fleet.bus.session import BusEndpoints, free_loopback_port, loopback_endpoint, open_session
from fleet.nodes.coordinator_node import CoordinatorNode
from scenes import load_scene


def test_an_event_of_a_later_tick_waits_for_its_decision_and_a_lie_is_still_dropped_and_counted():
    endpoint, keys = loopback_endpoint(free_loopback_port()), Keys("events_test")
    with (
        open_session(BusEndpoints(listen=(endpoint,))) as coordinator_side,
        open_session(BusEndpoints(connect=(endpoint,))) as sim_side,
    ):
        node = CoordinatorNode(coordinator_side, keys, load_scene("assembly_line"))
        time.sleep(0.5)  # the two sessions meet
        events = [
            LineEvent("arrived", 0, 3, "bases", 0),
            LineEvent("arrived", 1, 15, "tops", 0),
            LineEvent("arrived", 1, 16, "tops", 0),
        ]
        for e in events:
            sim_side.put(keys.events, encode(e))
        deadline = time.monotonic() + 10
        while node.events_seen < len(events) and time.monotonic() < deadline:
            node.poll()
            time.sleep(0.01)
        assert node.events_seen == 3 and node.dispatcher.ledger.parts == {}, (
            "counted on arrival, applied at their decision"
        )
        node.events.apply(10)  # what the decision at tick 10 does first
        assert list(node.dispatcher.ledger.parts) == [0], (
            "the decision at tick 10 sees the base, not the top of tick 15"
        )
        report = node.report()  # the run is over: the rest applies
        assert report["parts_spawned"] == 2 and report["dropped_messages"] == 1, (
            "part 1 arriving twice is a lie: dropped and counted"
        )
