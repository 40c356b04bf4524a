"""The coordinator's parts from perception: each decision works from the newest frame usable at its tick, carried to
that tick by the parts' motion; what cannot be perception's is refused with a reason."""

import numpy as np

from fleet.bus.messages import PartsState
from fleet.nodes.seen_parts import SeenParts
from fleet.sight.line_sight import carried_to
from perception.seen_ticks import SeenTicks

HZ = 100.0


def frame(tick: int, x: float = 0.0) -> PartsState:
    return PartsState(tick, tick / HZ, (4,), ("f",), (0,), (x, 0.3, 0.1), (1.0, 0, 0, 0), (0.1, 0.0, 0.0), (0.02,) * 3)


def test_a_frame_carried_to_a_later_tick_moves_its_parts_by_their_velocity():
    later = carried_to(frame(20, x=0.5), 45, HZ)
    assert later.tick == 45 and np.isclose(later.sim_time_s, 0.45)
    assert np.allclose(later.positions, (0.525, 0.3, 0.1)), "0.25 s at 0.1 m/s along x"


def test_a_decision_waits_for_its_frame_and_works_from_it_carried_to_its_tick():
    seen = SeenParts(SeenTicks([5.0], HZ))  # frames at 0, 20, 40...; usable 5 ticks after
    assert seen.ready(4), "no frame is usable yet: nothing to wait for"
    assert not seen.ready(30)
    seen.take(frame(20))
    assert seen.ready(30) and not seen.ready(45)
    views, time_s = seen.views(30)
    assert np.allclose(views[4].position, (0.01, 0.3, 0.1)) and time_s == 0.3
    report = seen.report(HZ, 0.2)
    assert report["latency_p50_frames"] == 0.5 and report["decisions_without_their_frame"] == 0


def test_parts_of_a_tick_no_camera_takes_a_frame_at_are_not_perceptions():
    seen = SeenParts(SeenTicks([5.0], HZ))
    assert "no camera takes a frame" in seen.problem(frame(7))
    assert seen.problem(frame(40)) == ""
    broken = PartsState(40, 0.4, (4, 5), ("f",), (0,), (0.0,) * 3, (1.0, 0, 0, 0), (0.0,) * 3, (0.02,) * 3)
    assert seen.problem(broken) != ""
