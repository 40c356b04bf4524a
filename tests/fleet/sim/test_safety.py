"""The plant's safety layer over a real world: goals that would bring two arms together are refused with a reason,
a storm of them leaves no contact, joint speeds above a robot's limits are refused, and a motion that finds another
arm too close is stopped."""

import dataclasses

import numpy as np
import pytest

from coordinator.geometry import separation_m
from fleet.sim.tracking import TrackedArms
from fleet.sim.world import World
from robots.joint_trajectory import GoalStatus, ResultCode, TrajectoryGoal, rest_to_rest
from scenes import load_scene


@pytest.fixture(scope="module")
def cell():
    """The sorting line: arms in a row, each able to reach into its neighbours."""
    return load_scene("sorting_line")


def _run(world: World, tracked: TrackedArms, seconds: float) -> int:
    """Step the world; the number of ticks with a contact between two arms."""
    contact_ticks = 0
    for _ in range(int(seconds / world.control_dt_s)):
        tracked.apply()
        world.step()
        tracked.update()
        contact_ticks += bool(world.inter_arm_contacts())
    return contact_ticks


def _poses_into(tracked: TrackedArms, arm: str, other: str, count: int, seed: int = 0) -> list[np.ndarray]:
    """Joint positions of `arm` (within its limits) that put it inside `other` as `other` stands now."""
    rng, safety = np.random.default_rng(seed), tracked.safety
    me, them, tracker = safety.geometries[arm], safety.geometries[other], tracked.trackers[arm]
    them.place(tracked.trackers[other].hold_q)
    found = []
    for _ in range(20000):
        q = rng.uniform(tracker.lower, tracker.upper)
        me.place(q)
        if separation_m(me, them) < 0.005:
            found.append(q)
            if len(found) == count:
                break
    assert len(found) == count, "the cell's arms can reach each other"
    return found


def test_a_goal_into_another_arm_is_refused_with_a_reason_and_the_arm_keeps_still(cell):
    world = World(cell)
    tracked = TrackedArms(world)
    names = tuple(world.arms["arm_0"].spec.arm_joints)
    (q,) = _poses_into(tracked, "arm_0", "arm_1", 1)
    results = tracked.submit("arm_0", rest_to_rest(7, names, q, 3.0, None))
    assert [(r.goal_id, r.status, r.code) for r in results] == [(7, GoalStatus.REJECTED, ResultCode.INVALID_GOAL)]
    assert "safety: its path comes within" in results[0].reason and "arm_1" in results[0].reason
    assert tracked.trackers["arm_0"].idle
    assert tracked.safety.counts.refused["separation"] == 1


def test_a_storm_of_goals_aimed_at_each_other_never_brings_the_arms_into_contact(cell):
    world = World(cell)
    tracked = TrackedArms(world)
    refused = accepted = 0
    rng = np.random.default_rng(1)
    for k, q in enumerate(_poses_into(tracked, "arm_0", "arm_1", 10) + _poses_into(tracked, "arm_1", "arm_0", 10)):
        arm = "arm_0" if k < 10 else "arm_1"
        goal = rest_to_rest(100 + k, tuple(world.arms[arm].spec.arm_joints), q, float(rng.uniform(0.5, 2.0)), None)
        for r in tracked.submit(arm, goal):
            refused += r.status == GoalStatus.REJECTED
        accepted += tracked.trackers[arm].goal_id == goal.goal_id
        assert _run(world, tracked, 0.3) == 0
    assert _run(world, tracked, 3.0) == 0
    assert refused >= 10 and refused + accepted == 20


def test_a_goal_faster_than_a_joint_may_turn_is_refused_naming_the_joint(cell):
    world = World(cell)
    tracked = TrackedArms(world)
    arm = world.arms["arm_0"]
    q = tracked.trackers["arm_0"].hold_q.copy()
    q[0] += 0.5
    results = tracked.submit("arm_0", rest_to_rest(3, tuple(arm.spec.arm_joints), q, 0.05, None))
    assert results[0].status == GoalStatus.REJECTED
    assert f"{arm.spec.arm_joints[0]} would turn at" in results[0].reason and "its limit is" in results[0].reason


def test_a_motion_that_finds_another_arm_too_close_is_stopped_and_held(cell):
    """arm_1 is put where arm_0's accepted path will pass (an arm pushed there, a plant out of step): arm_0 stops."""
    world = World(cell)
    tracked = TrackedArms(world)
    names = tuple(world.arms["arm_0"].spec.arm_joints)
    home = tracked.trackers["arm_1"].hold_q.copy()
    (into,) = _poses_into(tracked, "arm_0", "arm_1", 1, seed=3)
    # with arm_1 out of the way (folded to one side), the same target is accepted ...
    tracked.safety.geometries["arm_1"].place(home)
    far = _far_pose(tracked, "arm_1", "arm_0", into)
    tracked.trackers["arm_1"].hold_q = far
    world.arms["arm_1"].set_qpos(np.concatenate([far, world.arms["arm_1"].qpos()[len(far) :]]))
    assert tracked.submit("arm_0", rest_to_rest(1, names, into, 3.0, None)) == []
    _run(world, tracked, 0.2)
    # ... then arm_1 is moved back into that path behind the layer's back
    tracked.trackers["arm_1"].hold_q = home
    world.arms["arm_1"].set_qpos(np.concatenate([home, world.arms["arm_1"].qpos()[len(home) :]]))
    assert _run(world, tracked, 3.5) == 0
    last = tracked.trackers["arm_0"].last
    assert last.status == GoalStatus.ABORTED and "safety stop" in last.reason
    assert tracked.safety.counts.stopped >= 1


def _far_pose(tracked: TrackedArms, arm: str, other: str, other_q: np.ndarray) -> np.ndarray:
    """A pose of `arm` well clear of `other` at `other_q` (and of `other`'s path from its hold to there)."""
    safety, rng = tracked.safety, np.random.default_rng(5)
    me, them, tracker = safety.geometries[arm], safety.geometries[other], tracked.trackers[arm]
    start = tracked.trackers[other].hold_q
    best, best_q = -1.0, None
    for _ in range(400):
        q = rng.uniform(tracker.lower, tracker.upper)
        me.place(q)
        gaps = []
        for u in np.linspace(0, 1, 11):
            them.place(start + u * (other_q - start))
            gaps.append(separation_m(me, them))
        gap = min(gaps)
        if gap > best:
            best, best_q = gap, q
    assert best > 0.1
    return best_q


HOUR_S = 3600.0


def held_for_an_hour(goal_id: int, names: tuple[str, ...], q: np.ndarray, duration_s: float) -> TrajectoryGoal:
    """A rest-to-rest move in `duration_s`, then its end held for an hour (a second point, the same)."""
    move = rest_to_rest(goal_id, names, q, duration_s, None)
    return dataclasses.replace(
        move,
        times_from_start_s=(duration_s, duration_s + HOUR_S),
        positions=move.positions * 2,
        velocities=move.velocities * 2,
        accelerations=move.accelerations * 2,
    )


def test_a_goal_that_holds_its_end_for_an_hour_is_checked_over_its_motion_and_costs_no_more(cell):
    """The hold does not hide a collision at its end, nor a joint too fast on the way; a goal that is fine runs,
    sampled while it moves only (an hour's samples stalled the sim for 73 ms a goal, ten hours' for 0.9 s and 288
    MB: the plant's cost grew with a goal's length, not its motion)."""
    world = World(cell)
    tracked = TrackedArms(world)
    names = tuple(world.arms["arm_0"].spec.arm_joints)
    (into,) = _poses_into(tracked, "arm_0", "arm_1", 1)
    (refused,) = tracked.submit("arm_0", held_for_an_hour(7, names, into, 3.0))
    assert refused.status == GoalStatus.REJECTED and "safety: its path comes within" in refused.reason
    fast = tracked.trackers["arm_0"].hold_q.copy()
    fast[0] += 0.5
    (refused,) = tracked.submit("arm_0", held_for_an_hour(8, names, fast, 0.05))
    assert refused.status == GoalStatus.REJECTED and "would turn at" in refused.reason
    slow = tracked.trackers["arm_0"].hold_q.copy()
    slow[0] += 0.1
    assert tracked.submit("arm_0", held_for_an_hour(9, names, slow, 1.0)) == []
    spline = tracked.trackers["arm_0"].active.spline
    assert spline.t_end_s - spline.t0_s == pytest.approx(1.0 + HOUR_S)
    assert spline.moves_until_s - spline.t0_s == pytest.approx(1.0)
    assert len(spline.grid_q) <= 1.0 / world.control_dt_s + 2, "sampled while it moves, not for the hour"
    assert _run(world, tracked, 1.5) == 0
    desired_q, desired_dq = tracked.trackers["arm_0"].desired(world.sim_time_s)
    assert np.array_equal(desired_q, slow) and not desired_dq.any(), "the hold drives its end, at rest"
    assert tracked.trackers["arm_0"].goal_id == 9, "the goal runs on through its hold"
