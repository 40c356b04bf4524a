"""A tracker's saved state: put back into a tracker built for the same arm, it goes on exactly as the one saved
(targets, results and state bytes at every tick after), mid-path, with a goal waiting and a claw goal ahead."""

import numpy as np
import pytest

from robots.joint_trajectory import GripperGoal, TrajectoryGoal
from robots.saved_state import SavedStateError, pack, unpack
from robots.tracker import ArmTracker
from robots.tracker_state import TrackerState, restore_tracker, tracker_state

DT_S = 0.01


def two_joint_tracker() -> ArmTracker:
    return ArmTracker(("a", "b"), np.array([-3.0, -3.0]), np.array([3.0, 3.0]), np.zeros(2), servo_period_s=DT_S)


def run(tracker: ArmTracker, ticks: range) -> list:
    """Targets and results of `ticks`, the arm following its targets exactly."""
    out = []
    for k in ticks:
        q, dq = tracker.desired(k * DT_S)
        out.append((q.tobytes(), dq.tobytes(), tracker.update(k * DT_S, q, np.zeros(2), np.zeros(2))))
    return out


def busy_tracker() -> ArmTracker:
    t = two_joint_tracker()
    t.submit(TrajectoryGoal(5, ("a", "b"), (0.5, 1.0), ((0.5, 0.2), (1.0, 0.4)), path_tolerance_rad=(0.1,)), 0.0)
    t.submit(GripperGoal(6, 0.3, start_time_s=0.5), 0.0)
    run(t, range(30))
    t.submit(TrajectoryGoal(7, ("b", "a"), (0.8,), ((-0.2, 0.3),), start_time_s=0.6), 0.3)  # waits for its start
    return t


def test_a_tracker_put_back_goes_on_exactly_as_the_one_saved():
    saved = busy_tracker()
    data = pack(tracker_state(saved))
    restored = two_joint_tracker()
    restore_tracker(restored, unpack(data, TrackerState))
    assert pack(tracker_state(restored)) == data
    assert run(restored, range(30, 200)) == run(saved, range(30, 200))
    assert pack(tracker_state(restored)) == pack(tracker_state(saved))


def test_a_holding_tracker_holds_the_same_point_object_as_before():
    saved = two_joint_tracker()
    saved.desired(0.0)
    restored = two_joint_tracker()
    restore_tracker(restored, unpack(pack(tracker_state(saved)), TrackerState))
    assert restored.desired(0.01)[0] is restored.hold_q, "held without a new target being made"


def test_a_state_of_another_shape_is_refused_naming_the_field():
    data = pack(tracker_state(busy_tracker())).replace(b"hold_q", b"hold_x")
    with pytest.raises(SavedStateError, match="hold_"):
        unpack(data, TrackerState)
