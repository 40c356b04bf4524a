"""How far arms can close on each other along their timed paths: a bound no point of an arm passes, and a walk that
steps long where the arms move slowly."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from coordinator.gap_closing import GapClosing, PathTravel
from coordinator.geometry import ArmGeometry
from coordinator.guard import TimedPath
from robots.frames import yaw_transform
from robots.registry import get_robot, is_available


def arm(robot: str) -> ArmGeometry:
    if not is_available(robot):
        pytest.skip("needs the models extra")
    return ArmGeometry("arm_0", get_robot(robot), yaw_transform((0.2, -0.1, 0.0), 0.7))


def random_path(geometry: ArmGeometry, rng: np.random.Generator, stages: int) -> TimedPath:
    lower, upper = geometry.km.lower[geometry.km.arm_q_index], geometry.km.upper[geometry.km.arm_q_index]
    q = [tuple(rng.uniform(lower, upper)) for _ in range(2 + stages)]
    after = tuple(np.cumsum(rng.uniform(0.1, 0.8, stages)).tolist())
    return TimedPath("arm_0", q[0], q[1], 1.0, 1.0 + rng.uniform(0.3, 3.0), tuple(q[2:]), after)


@settings(max_examples=40, deadline=None)
@given(
    robot=st.sampled_from(["openclaw", "so101", "panda"]),
    seed=st.integers(0, 2**31),
    stages=st.integers(0, 3),
    window=st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)),
)
def test_no_point_of_an_arm_moves_farther_between_two_times_than_its_travel_bound(robot, seed, stages, window):
    geometry = arm(robot)
    rng = np.random.default_rng(seed)
    path = random_path(geometry, rng, stages)
    travel = PathTravel(path, geometry.joint_levers_m())
    t0, t1 = sorted(path.t_start_s - 0.2 + (path.t_done_s - path.t_start_s + 0.4) * np.array(window))
    geometry.place(path.at(t0))
    before = geometry.cover_centres.copy()
    geometry.place(path.at(t1))
    moved = float(np.linalg.norm(geometry.cover_centres - before, axis=1).max())
    assert moved <= travel.at(t1) - travel.at(t0) + 1e-9


def test_the_walk_steps_long_near_the_ends_of_a_move_and_never_past_what_the_arms_could_close():
    geometry = arm("openclaw")
    levers = geometry.joint_levers_m()
    rng = np.random.default_rng(4)
    mine, other = random_path(geometry, rng, 0), random_path(geometry, rng, 0)  # both rest to rest, at once
    closing = GapClosing(PathTravel(mine, levers), {"arm_1": PathTravel(other, levers)})
    gap = 0.01
    at_peak = gap / closing.peak_m_per_s
    t, steps = mine.t_start_s, []
    while t < mine.t_done_s:
        after = closing.next_sample_s(t, gap, mine.t_done_s)
        assert after - t >= at_peak * (1 - 1e-9), "never shorter than the step at the peak speeds"
        assert closing.closed_m(t, after) <= gap + 1e-12, "never past what the arms could close"
        steps.append(after - t)
        t = after
    assert steps[0] > 5 * at_peak, "from rest, the arms close slowly: the first step is long"
    peak_walk = (mine.t_done_s - mine.t_start_s) / at_peak
    assert len(steps) < 0.6 * peak_walk, (len(steps), peak_walk)  # a quintic's mean speed is 1/1.875 of its peak


def test_arms_that_do_not_move_close_nothing_and_the_walk_ends_at_once():
    geometry = arm("openclaw")
    still = TimedPath("arm_0", tuple(geometry.spec.home_q), tuple(geometry.spec.home_q), 0.0, 2.0)
    closing = GapClosing(PathTravel(still, geometry.joint_levers_m()), {})
    assert closing.closed_m(0.0, 2.0) == 0.0
    assert closing.next_sample_s(0.0, 0.01, 2.0) == 2.0
