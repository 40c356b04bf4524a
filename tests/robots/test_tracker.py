"""The tracker as an arm's firmware runs it: goals checked and refused with control_msgs' codes, splines through
their points, splicing and preemption, tolerances, e-stop and watchdog. Pure computation: no simulator."""

import math

import numpy as np
import pytest

from robots.joint_trajectory import (
    GoalStatus,
    GripperGoal,
    ResultCode,
    Spline,
    TrajectoryGoal,
    check_goal,
    rest_to_rest,
)
from robots.tracker import ArmTracker
from robots.trajectory import JointSegment

NAMES = ("a", "b", "c")
LOWER, UPPER = np.full(3, -2.0), np.full(3, 2.0)
DT = 0.01


def tracker(**kw) -> ArmTracker:
    return ArmTracker(NAMES, LOWER, UPPER, np.zeros(3), servo_period_s=DT, **kw)


def goal(
    goal_id=1, times=(0.5, 1.0), positions=((0.2, 0.0, 0.0), (0.4, 0.1, 0.0)), joint_names=NAMES, **kw
) -> TrajectoryGoal:
    return TrajectoryGoal(goal_id, joint_names, times, positions, **kw)


@pytest.mark.parametrize(
    "bad, code, words",
    [
        (dict(joint_names=("a", "b", "x")), ResultCode.INVALID_JOINTS, "unknown joint names ['x']"),
        (dict(joint_names=("a", "b")), ResultCode.INVALID_JOINTS, "this arm's joints are a, b, c"),
        (dict(times_from_start_s=(1.0, 0.5)), ResultCode.INVALID_GOAL, "strictly increasing"),
        (dict(times_from_start_s=(0.5, 0.5)), ResultCode.INVALID_GOAL, "strictly increasing"),
        (dict(positions=((0.2, 0.0, 0.0), (3.0, 0.0, 0.0))), ResultCode.INVALID_GOAL, "beyond the limits of a"),
        (dict(positions=((0.2, math.nan, 0.0), (0.4, 0.1, 0.0))), ResultCode.INVALID_GOAL, "NaN"),
        (dict(positions=((0.2, 0.0), (0.4, 0.1))), ResultCode.INVALID_GOAL, "3 values"),
        (dict(positions=()), ResultCode.INVALID_GOAL, "no points"),
        (dict(velocities=(), accelerations=((0.0,) * 3,) * 2), ResultCode.INVALID_GOAL, "need velocities"),
        (dict(path_tolerance_rad=(0.1, 0.1)), ResultCode.INVALID_GOAL, "one per joint"),
        (dict(start_time_s=math.inf), ResultCode.INVALID_GOAL, "start time"),
    ],
)
def test_an_invalid_goal_is_refused_with_its_code_and_reason_and_the_arm_holds(bad, code, words):
    t = tracker()
    fields = (
        dict(goal_id=1, joint_names=NAMES, times_from_start_s=(0.5, 1.0), positions=((0.2, 0.0, 0.0), (0.4, 0.1, 0.0)))
        | bad
    )
    (result,) = t.submit(TrajectoryGoal(**fields), now_s=0.0)
    assert result.status == GoalStatus.REJECTED and result.code == code and words in result.reason
    q, dq = t.desired(0.5)
    assert np.array_equal(q, np.zeros(3)) and not dq.any(), "nothing moves"


def test_joints_may_come_in_any_order_and_are_put_in_the_arms():
    checked = check_goal(
        goal(joint_names=("c", "a", "b"), positions=((0.3, 0.1, 0.2), (0.0, 0.0, 0.0))), NAMES, LOWER, UPPER
    )
    assert np.allclose(checked.positions[0], [0.1, 0.2, 0.3])


def test_a_rest_to_rest_goal_is_the_quintic_segment_and_ends_successful():
    t = tracker()
    target = np.array([0.5, -0.3, 0.2])
    assert t.submit(rest_to_rest(7, NAMES, target, 1.0, 0.2, goal_tolerance_rad=(0.01,)), now_s=0.0) == []
    segment = JointSegment(np.zeros(3), target, 0.2, 1.0)
    for k in range(0, 121):
        now = k * DT
        q, dq = t.desired(now)
        want_q, want_dq = segment.sample(now)
        assert np.allclose(q, want_q, atol=1e-9) and np.allclose(dq, want_dq, atol=1e-9)
        results = t.update(now, q, np.zeros(1), np.zeros(1))  # a perfect arm
        if now < 1.2 - 1e-9:
            assert results == []
    assert [(r.goal_id, r.status, r.code) for r in results] == [(7, GoalStatus.SUCCEEDED, ResultCode.SUCCESSFUL)]
    assert np.allclose(t.desired(1.5)[0], target), "holds the last point"


def test_cubic_and_quintic_splines_pass_through_every_point_with_its_velocity():
    times, positions = (0.5, 1.0, 1.6), ((0.2, 0.0, 0.0), (0.4, 0.1, 0.0), (0.1, 0.3, -0.2))
    velocities = ((0.5, 0.2, 0.0), (0.0, 0.3, -0.1), (0.0, 0.0, 0.0))
    for accelerations in ((), ((0.0,) * 3,) * 3):
        checked = check_goal(
            goal(times=times, positions=positions, velocities=velocities, accelerations=accelerations),
            NAMES,
            LOWER,
            UPPER,
        )
        spline = Spline.through(2.0, np.zeros(3), np.zeros(3), np.zeros(3), checked, DT)
        for t_s, p, v in zip(times, positions, velocities):
            q, dq = spline.state(2.0 + t_s)
            assert np.allclose(q, p) and (t_s == times[-1] or np.allclose(dq, v))


def test_a_goal_starting_later_is_spliced_in_and_preempts_the_running_one():
    t = tracker()
    t.submit(rest_to_rest(1, NAMES, np.array([1.0, 0.0, 0.0]), 2.0, None), now_s=0.0)
    q_at_1 = t.desired(1.0)[0].copy()
    (preempted,) = t.submit(rest_to_rest(2, NAMES, np.array([0.0, 0.5, 0.0]), 1.0, 1.0), now_s=0.5)
    assert preempted.goal_id == 1 and preempted.status == GoalStatus.PREEMPTED and "goal 2" in preempted.reason
    assert t.goal_id == 2
    first = JointSegment(np.zeros(3), np.array([1.0, 0.0, 0.0]), 0.0, 2.0)
    assert np.allclose(t.desired(0.9)[0], first.sample(0.9)[0]), "the old path runs until the new goal's start"
    assert np.allclose(t.desired(1.0)[0], q_at_1, atol=1e-9), "and the new one begins where it was"
    assert np.allclose(t.desired(2.0)[0], [0.0, 0.5, 0.0])
    assert t.update(2.0, np.array([0.0, 0.5, 0.0]), np.zeros(1), np.zeros(1))[0].goal_id == 2


def test_a_goal_that_replaces_a_pending_one_starts_from_the_path_that_really_runs():
    """A pending goal (future start) replaced by a newer one never runs: the newer one starts from the path the arm
    follows until then (the running goal's), with no jump at its start."""
    t = tracker()
    t.submit(rest_to_rest(1, NAMES, np.array([1.0, 0.0, 0.0]), 2.0, None), now_s=0.0)
    t.submit(rest_to_rest(2, NAMES, np.array([-1.0, 0.5, 0.0]), 1.0, 1.0), now_s=0.2)  # pending from 1.0 s
    (replaced,) = t.submit(rest_to_rest(3, NAMES, np.array([0.0, 0.5, 0.5]), 1.0, 1.5), now_s=0.4)
    assert replaced.goal_id == 2 and replaced.status == GoalStatus.PREEMPTED
    first = JointSegment(np.zeros(3), np.array([1.0, 0.0, 0.0]), 0.0, 2.0)
    before = t.desired(1.5 - DT)[0].copy()
    assert np.allclose(before, first.sample(1.5 - DT)[0], atol=1e-9), "goal 1 runs until goal 3's start"
    at_start = t.desired(1.5)[0]
    assert np.allclose(at_start, first.sample(1.5)[0], atol=1e-9), "goal 3 begins where goal 1 is, not goal 2"
    assert np.abs(at_start - before).max() < 0.05


def test_a_joint_off_its_path_aborts_the_goal_and_the_arm_holds_where_it_is():
    t = tracker()
    t.submit(rest_to_rest(3, NAMES, np.array([1.0, 0.0, 0.0]), 1.0, None, path_tolerance_rad=(0.05,)), now_s=0.0)
    t.desired(0.5)
    stuck = np.array([0.1, 0.0, 0.0])  # blocked well short of where the path wants it
    (result,) = t.update(0.5, stuck, np.zeros(1), np.zeros(1))
    assert (
        result.code == ResultCode.PATH_TOLERANCE_VIOLATED
        and result.status == GoalStatus.ABORTED
        and "a " in result.reason
    )
    assert np.allclose(t.desired(0.6)[0], stuck) and t.goal_id == 0


def test_an_arm_that_never_gets_there_ends_goal_tolerance_violated():
    t = tracker()
    t.submit(
        rest_to_rest(
            4, NAMES, np.array([0.5, 0.0, 0.0]), 0.5, None, goal_tolerance_rad=(0.01,), goal_time_tolerance_s=0.2
        ),
        0.0,
    )
    short = np.array([0.4, 0.0, 0.0])
    assert t.update(0.6, short, np.zeros(1), np.zeros(1)) == [], "within the goal time tolerance: still waiting"
    (result,) = t.update(0.75, short, np.zeros(1), np.zeros(1))
    assert result.code == ResultCode.GOAL_TOLERANCE_VIOLATED


def test_estop_aborts_every_goal_holds_and_refuses_new_ones_until_released():
    t = tracker()
    t.submit(rest_to_rest(5, NAMES, np.array([0.5, 0.0, 0.0]), 1.0, None), 0.0)
    t.submit(GripperGoal(6, 0.0, start_time_s=0.0), 0.0)
    here = t.desired(0.3)[0].copy()
    results = t.set_estop(True, 0.3, here)
    assert {(r.goal_id, r.status, r.code) for r in results} == {
        (5, GoalStatus.ABORTED, ResultCode.ABORTED),
        (6, GoalStatus.ABORTED, ResultCode.ABORTED),
    }
    assert all(r.reason == "emergency stop" for r in results)
    assert np.allclose(t.desired(0.8)[0], here)
    (refused,) = t.submit(rest_to_rest(7, NAMES, np.zeros(3), 1.0, None), 0.4)
    assert refused.status == GoalStatus.REJECTED and "emergency stop" in refused.reason
    t.set_estop(False, 0.5, here)
    assert t.submit(rest_to_rest(8, NAMES, np.zeros(3), 1.0, None), 0.5) == []


def test_the_watchdog_stops_the_arm_when_its_controller_misses_its_deadline():
    t = tracker()
    t.submit(rest_to_rest(9, NAMES, np.array([1.0, 0.0, 0.0]), 2.0, None), 0.0)
    t.watch(0.25)
    assert t.update(0.25, t.desired(0.25)[0], np.zeros(1), np.zeros(1)) == []
    here = t.desired(0.26)[0].copy()
    (result,) = t.update(0.26, here, np.zeros(1), np.zeros(1))
    assert result.status == GoalStatus.ABORTED and result.reason.startswith("watchdog")
    assert np.allclose(t.desired(1.0)[0], here), "held, not run out to the trajectory's end"


def test_a_gripper_goal_ends_reached_or_stalled_on_a_part():
    t = tracker(opening_of=lambda g: float(g[0]))
    t.submit(GripperGoal(10, 0.0), 0.0)
    assert t.gripper_opening() == 0.0
    results = []
    for k in range(1, 30):  # the claw stops at 0.4: closed on a part
        results += t.update(k * DT, np.zeros(3), np.array([0.4]), np.array([0.0]))
    assert [(r.goal_id, r.reached, r.stalled) for r in results] == [(10, False, True)]
    t.submit(GripperGoal(11, 1.0), 0.3)
    (opened,) = t.update(0.31, np.zeros(3), np.array([1.0]), np.array([0.0]))
    assert opened.reached and not opened.stalled
    (bad,) = t.submit(GripperGoal(12, 1.5), 0.4)
    assert bad.status == GoalStatus.REJECTED and "[0, 1]" in bad.reason
