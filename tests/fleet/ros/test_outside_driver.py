"""An arm a ROS client drives is taken: its own controller does not fight the client's goal (it waits), the
coordinator gives it nothing and takes back what it had, and once the client lets go the arm is the line's again."""

import pytest

from tests.fleet.ros.rosbridge_session import taken_arm_session
from tests.fleet.test_run import QUICK_LINE, assert_nothing_left

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out


def test_an_arm_driven_from_outside_is_taken_until_let_go():
    summary, seen = taken_arm_session(QUICK_LINE)
    assert "error" not in seen, seen["error"]
    held = seen["held"]
    assert held["accepted"] and held["status"] == 4, ("the client's goal ran to its end, not preempted", held)
    events = [(e["arm"], e["event"]) for e in summary["arm_events"]]
    assert ("arm_0", "taken") in events and ("arm_0", "let go") in events, events
    assert events.index(("arm_0", "taken")) < events.index(("arm_0", "let go"))
    assert ("arm_0", "lost") not in events and summary["arms_lost"] == [], "its controller waited, alive"
    assert summary["status"] == "interrupted", summary["error"]  # stopped once the user had let go
    assert summary["inter_arm_contacts"] == 0 and summary["parts_spawned"] >= 1
    assert_nothing_left(summary, seen["endpoint"])
