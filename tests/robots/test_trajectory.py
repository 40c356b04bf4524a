import numpy as np

from robots.joint_trajectory import Spline, check_goal, rest_to_rest
from robots.trajectory import SPLICE_SPEED_FRACTION, JointSegment, spliced_duration_s


def test_segment_respects_velocity_limits_and_ends_at_rest():
    limit = np.array([1.0, 2.0])
    seg = JointSegment.timed(np.zeros(2), np.array([1.0, -1.0]), 2.0, limit, speed_fraction=0.5)
    times = np.linspace(seg.t0_s, seg.t_end_s, 200)
    speeds = np.array([np.abs(seg.sample(t)[1]) for t in times])
    assert np.all(speeds <= 0.5 * limit + 1e-9)
    q_end, dq_end = seg.sample(seg.t_end_s + 1.0)
    np.testing.assert_allclose(q_end, [1.0, -1.0])
    np.testing.assert_allclose(dq_end, 0.0)


def spliced_peak(moving: JointSegment, start_s: float, q_end: np.ndarray, duration_s: float) -> np.ndarray:
    """Each joint's peak speed as the plant's tracker runs a rest-to-rest goal spliced into `moving` at `start_s`."""
    names = tuple(f"j{k}" for k in range(len(q_end)))
    goal = rest_to_rest(1, names, q_end, duration_s, start_s)
    checked = check_goal(goal, names, np.full(len(q_end), -10.0), np.full(len(q_end), 10.0))
    spline = Spline.through(start_s, *moving.state_at(start_s), checked, period_s=0.005)
    return np.abs(spline.grid_dq).max(axis=0)


def test_a_move_spliced_into_a_moving_arm_is_stretched_to_keep_within_the_joints_limits():
    limit = np.full(3, 2.5)
    home = JointSegment.timed(np.array([2.1, 0.7, 1.4]), np.array([0.0, -0.2, 1.9]), 10.0, limit, 1.0)
    start_s, hover = 10.8, np.array([1.5, 0.9, 1.2])  # at speed towards home; the next task lies back the way it came
    q0 = home.sample(start_s)[0]
    at_rest = JointSegment.timed(q0, hover, start_s, limit, 1.0).duration_s
    assert spliced_peak(home, start_s, hover, at_rest).max() > 1.1 * 2.5, "timed as from rest: the plant refuses it"
    stretched = spliced_duration_s(home, start_s, hover, at_rest, limit)
    assert at_rest < stretched < 2 * at_rest
    allowed = np.maximum(limit * SPLICE_SPEED_FRACTION, np.abs(home.sample(start_s)[1]))  # (as fast as it turns)
    assert np.all(spliced_peak(home, start_s, hover, stretched) <= allowed + 1e-6) and np.all(allowed <= limit)
    assert spliced_duration_s(home, home.t_end_s + 0.1, hover, at_rest, limit) == at_rest, "from rest: as timed"


def test_a_move_no_stretch_keeps_within_the_limits_is_left_to_start_at_rest():
    limit = np.full(3, 2.5)
    home = JointSegment.timed(np.array([2.1, 0.7, 1.4]), np.array([0.0, -0.2, 1.9]), 10.0, limit, 1.0)
    start_s, hover = 10.5, np.array([-0.9, 0.9, 1.2])  # on past home and back: overshoots more the longer it takes
    at_rest = JointSegment.timed(home.sample(start_s)[0], hover, start_s, limit, 1.0).duration_s
    assert spliced_duration_s(home, start_s, hover, at_rest, limit) is None


def test_a_goal_may_move_for_600_s_and_hold_its_end_as_long_as_it_says():
    from robots.joint_trajectory import MAX_MOVING_S, CheckedGoal, GoalStatus, TrajectoryGoal, check_goal

    names, low, high = ("a", "b"), np.full(2, -3.0), np.full(2, 3.0)

    def checked(times, positions, velocities=()):
        return check_goal(TrajectoryGoal(1, names, times, positions, velocities), names, low, high)

    assert isinstance(checked((1.0, 1e9), ((0.1, 0.1), (0.1, 0.1))), CheckedGoal), "a hold of any length"
    assert isinstance(checked((MAX_MOVING_S,), ((0.1, 0.1),)), CheckedGoal)
    too_long = checked((1.0, MAX_MOVING_S + 1.0), ((0.1, 0.1), (0.2, 0.1)))
    assert too_long.status == GoalStatus.REJECTED
    assert too_long.reason == (
        "the trajectory moves for 601 s; a goal may move for at most 600 s (its last point may be held as long as "
        "it says)"
    )
    # a point the same as the one before, but still moving through it, moves
    moving = checked((1.0, 700.0), ((0.1, 0.1), (0.1, 0.1)), ((0.0, 0.0), (0.5, 0.0)))
    assert moving.status == GoalStatus.REJECTED and "moves for 700 s" in moving.reason
