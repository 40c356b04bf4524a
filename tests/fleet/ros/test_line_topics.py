"""The ROS front ends' rate cap: views beyond `max_rate_hz` are held back, and the newest of them goes out once
the cap allows, so that a watcher of a line that pauses or stops sees where it stands (every front end flushes it
each round: rosbridge, rmw_zenoh, Foxglove)."""

import time

from fleet.bus.messages import LineView, PartsState
from fleet.ros import names
from fleet.ros.line_topics import LineTopics
from scenes import load_scene


def view(sim_time_s: float) -> LineView:
    parts = PartsState(0, sim_time_s, (), (), (), (), (), (), ())
    return LineView(round(sim_time_s * 100), sim_time_s, (), parts)


def clocks(out: list[tuple[str, object]]) -> list[float]:
    return [m.clock.sec + m.clock.nanosec * 1e-9 for topic, m in out if topic == names.CLOCK]


def test_the_newest_view_the_cap_held_back_goes_out_once_the_cap_allows():
    topics, wanted = LineTopics(load_scene("pick_cell"), max_rate_hz=10.0), {names.CLOCK}
    assert clocks(topics.from_view(view(19.8), wanted)) == [19.8]
    assert topics.from_view(view(19.9), wanted) == [] and topics.from_view(view(20.0), wanted) == [], "capped"
    assert topics.held_back(wanted) == [], "not before the cap's period"
    time.sleep(0.11)
    assert clocks(topics.held_back(wanted)) == [20.0], "the line paused at 20 s: its watchers see 20 s"
    assert topics.held_back(wanted) == [], "once"


def test_a_view_let_through_leaves_nothing_held_back():
    topics, wanted = LineTopics(load_scene("pick_cell"), max_rate_hz=10.0), {names.CLOCK}
    topics.from_view(view(1.0), wanted)
    topics.from_view(view(1.1), wanted)  # held back
    time.sleep(0.11)
    assert clocks(topics.from_view(view(1.2), wanted)) == [1.2]
    time.sleep(0.11)
    assert topics.held_back(wanted) == []
