"""Taking an arm and giving it back (`OutsideHold` through `TrackedArms`, on the real physics): an accepted outside
goal takes the arm and cancels what its controller sent before; the arm is let go `OUTSIDE_RELEASE_S` after the
last outside goal stops driving it, whichever way it stopped."""

from __future__ import annotations

import numpy as np
import pytest

from fleet.sim.outside_hold import OUTSIDE_RELEASE_S
from fleet.sim.tracking import TrackedArms
from fleet.sim.world import World
from robots.joint_trajectory import OUTSIDE_REASON, GoalStatus, GripperGoal, rest_to_rest
from scenes import load_scene

pytestmark = pytest.mark.slow  # physics worlds


@pytest.fixture
def line() -> tuple[World, TrackedArms]:
    world = World(load_scene("sorting_line", arms=2))
    return world, TrackedArms(world)


def run(world: World, tracked: TrackedArms, seconds: float) -> dict[int, GoalStatus]:
    """Step the world `seconds`: the goals that ended meanwhile, by id."""
    ended = {}
    for _ in range(int(round(seconds / world.control_dt_s))):
        tracked.apply()
        world.step()
        for results in tracked.update().values():
            ended |= {r.goal_id: r.status for r in results}
    return ended


def goal(tracked: TrackedArms, goal_id: int, lift_rad: float, seconds: float):
    """A goal for arm_0 to home with its shoulder lifted by `lift_rad` (clear of arm_1), in `seconds`."""
    spec_q = np.asarray(tracked.world.arms["arm_0"].spec.home_q, float)
    names = tuple(tracked.world.arms["arm_0"].spec.arm_joints)
    return rest_to_rest(goal_id, names, spec_q + np.r_[0.0, -lift_rad, 0, 0, 0, 0], seconds, None)


def let_go_after(world: World, tracked: TrackedArms, limit_s: float) -> float:
    """Sim seconds from now until arm_0 is no longer taken (inf past `limit_s`)."""
    start = world.sim_time_s
    while tracked.taken("arm_0"):
        if world.sim_time_s - start > limit_s:
            return float("inf")
        run(world, tracked, 0.1)
    return world.sim_time_s - start


def test_a_goal_that_ends_lets_go_two_seconds_later(line):
    world, tracked = line
    assert not tracked.taken("arm_0")
    tracked.submit("arm_0", goal(tracked, 1, 0.2, 1.0), outside=True)
    assert tracked.taken("arm_0")
    refused = tracked.submit("arm_0", goal(tracked, 2, 0.1, 1.0))
    assert refused[0].status == GoalStatus.REJECTED and refused[0].reason.startswith(OUTSIDE_REASON)
    assert let_go_after(world, tracked, 10.0) == pytest.approx(1.0 + OUTSIDE_RELEASE_S, abs=0.3)
    assert not tracked.submit("arm_0", goal(tracked, 3, 0.1, 1.0)), "its controller drives it again"


def test_a_long_goal_replaced_by_a_short_one_lets_go_after_the_short_one(line):
    world, tracked = line
    tracked.submit("arm_0", goal(tracked, 1, 0.3, 30.0), outside=True)
    run(world, tracked, 1.0)
    tracked.submit("arm_0", goal(tracked, 2, 0.1, 1.0), outside=True)
    assert let_go_after(world, tracked, 10.0) < 1.0 + OUTSIDE_RELEASE_S + 0.5


def test_a_cancelled_goal_lets_go_after_the_client_s_hold(line):
    """A ROS cancel is a short hold goal of the client's (`fleet.ros.line_actions`)."""
    world, tracked = line
    tracked.submit("arm_0", goal(tracked, 1, 0.3, 30.0), outside=True)
    run(world, tracked, 3.0)
    q = world.arms["arm_0"].qpos()[:6]
    names = tuple(world.arms["arm_0"].spec.arm_joints)
    tracked.submit("arm_0", rest_to_rest(2, names, q, 0.1, None), outside=True)
    assert let_go_after(world, tracked, 10.0) < 0.1 + OUTSIDE_RELEASE_S + 0.5


def test_an_estop_that_aborts_the_outside_goal_lets_go(line):
    world, tracked = line
    tracked.submit("arm_0", goal(tracked, 1, 0.3, 30.0), outside=True)
    run(world, tracked, 1.0)
    tracked.set_estop(True)
    assert let_go_after(world, tracked, 10.0) == pytest.approx(OUTSIDE_RELEASE_S, abs=0.3)


def test_a_refused_outside_goal_takes_nothing(line):
    world, tracked = line
    names = tuple(world.arms["arm_0"].spec.arm_joints)
    results = tracked.submit("arm_0", rest_to_rest(1, names, np.full(6, 99.0), 1.0, None), outside=True)
    assert results[0].status == GoalStatus.REJECTED and not tracked.taken("arm_0")


def test_the_take_cancels_the_claw_goal_its_controller_sent_to_start_later(line):
    """The issue's contact: a claw close the skill had sent before the arm was taken still ran after the take."""
    world, tracked = line
    tracked.submit("arm_0", GripperGoal(7, 0.0, start_time_s=world.sim_time_s + 1.0))
    results = tracked.submit("arm_0", goal(tracked, 8, 0.2, 2.0), outside=True)
    cancelled = [r for r in results if r.goal_id == 7]
    assert cancelled and cancelled[0].status == GoalStatus.ABORTED and cancelled[0].reason.startswith(OUTSIDE_REASON)
    run(world, tracked, 2.0)
    assert tracked.trackers["arm_0"].gripper_opening() == pytest.approx(1.0), "the claw never closed"


def test_a_claw_goal_that_takes_the_arm_stops_the_controller_s_path(line):
    world, tracked = line
    tracked.submit("arm_0", goal(tracked, 1, 0.3, 3.0))
    run(world, tracked, 0.5)
    results = tracked.submit("arm_0", GripperGoal(2, 0.5), outside=True)
    assert [r.status for r in results if r.goal_id == 1] == [GoalStatus.ABORTED]
    held = world.arms["arm_0"].qpos()[:6].copy()
    run(world, tracked, 1.0)
    assert np.abs(world.arms["arm_0"].qpos()[:6] - held).max() < 0.05, "the arm holds where the take found it"
    assert let_go_after(world, tracked, 10.0) < OUTSIDE_RELEASE_S + 1.0
