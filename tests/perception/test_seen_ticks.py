"""Frame ticks and the newest frame a node may act on: every node of a lockstep line works from the same frame."""

import pytest

from perception.seen_ticks import SeenTicks, frame_due, frame_tick


@pytest.mark.parametrize("rate_hz, control_hz", [(5, 500), (7, 500), (30, 60), (3, 100), (60, 500)])
def test_the_nth_frame_tick_is_the_nth_tick_a_frame_falls_on(rate_hz, control_hz):
    due = [t for t in range(3000) if frame_due(t, rate_hz, control_hz)]
    assert [frame_tick(k, rate_hz, control_hz) for k in range(len(due))] == due


def test_a_frame_is_usable_its_latency_after_it_was_taken():
    ticks = SeenTicks([5.0], 500.0, latency_s=0.05)  # frames at 0, 100, 200...; usable 25 ticks later
    assert [ticks.usable_at(t) for t in (0, 24, 25, 124, 125, 300)] == [-1, -1, 0, 0, 100, 200]


def test_with_two_cameras_the_newest_frame_of_either_is_usable():
    ticks = SeenTicks([5.0, 2.0], 500.0, latency_s=0.0)
    assert ticks.due(100) and ticks.due(250) and not ticks.due(150)
    assert ticks.usable_at(260) == 250 and ticks.usable_at(199) == 100


def test_no_camera_is_an_error():
    with pytest.raises(ValueError, match="at least one camera"):
        SeenTicks([], 500.0)
