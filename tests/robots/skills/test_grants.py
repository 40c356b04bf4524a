"""A skill that must ask before each free move: it holds until granted, gives an approach back when denied,
asks again for a transfer it cannot abandon, re-plans an approach kept waiting while the part moves on, and goes
home when released from an e-stop after letting its part go."""

import numpy as np

from robots.failures import FailureCode
from robots.frames import yaw_transform
from robots.joint_trajectory import GripperGoal, TrajectoryGoal
from robots.registry import get_robot
from robots.skills.interface import ArmObservation, PartObservation, PickPlaceJob
from robots.skills.pick_place import REPLAN_AFTER_S, Phase, PickPlaceSkill

SPEC = get_robot("openclaw")
BASE = yaw_transform((0.0, -0.35, 0.0), np.pi / 2)
DT = 0.01


def obs(skill_or_q, t: float) -> ArmObservation:
    q = np.asarray(skill_or_q, float)
    return ArmObservation(t, q, np.zeros_like(q), np.array(SPEC.gripper_open))


def part_at(x: float, t: float = 0.0, velocity=(0.0, 0.0, 0.0)) -> PartObservation:
    position = np.array([x + velocity[0] * t, 0.0, 0.095])
    return PartObservation(7, position, np.array([1.0, 0, 0, 0]), np.array(velocity), 0.05, 0.03, (0.05, 0.05, 0.03))


def started(velocity=(0.0, 0.0, 0.0)) -> PickPlaceSkill:
    skill = PickPlaceSkill(SPEC, BASE, grants_required=True)
    task = PickPlaceJob(7, 0.08, (0.3, -0.55, 0.04), velocity)
    skill.start(task, obs(SPEC.home_q, 0.0), part_at(0.0, 0.0, velocity))
    return skill


def test_the_approach_waits_for_its_grant_then_moves():
    skill = started()
    assert skill.phase == Phase.APPROACH and skill.request is not None
    request = skill.request
    assert np.allclose(request.q_from, SPEC.home_q) and request.duration_s > 0
    first = skill.step(obs(SPEC.home_q, 0.0), {7: part_at(0.0)})
    assert [type(g) for g in first] == [GripperGoal], (
        "the claw opens for the part; the arm holds, sending no trajectory"
    )
    for k in range(1, 20):  # no answer yet: still no trajectory
        assert skill.step(obs(SPEC.home_q, k * DT), {7: part_at(0.0)}) == []
    skill.on_grant(request.seq + 5, "grant", "", 0.2)  # a stale or foreign answer changes nothing
    assert skill.request is request
    skill.on_grant(request.seq, "grant", "", 0.2, start_time_s=0.25)
    assert skill.request is None
    goals = skill.step(obs(SPEC.home_q, 0.2), {7: part_at(0.0)})
    assert len(goals) == 1 and isinstance(goals[0], TrajectoryGoal), "granted: the move goes to the tracker"
    move = goals[0]
    assert move.start_time_s == 0.25, "from the time the grant names"
    assert np.allclose(move.positions[-1], request.q_to) and np.isclose(move.times_from_start_s[-1], request.duration_s)
    assert move.joint_names == SPEC.arm_joints


def test_a_denied_approach_gives_the_task_back_with_the_arm_in_the_way():
    skill = started()
    skill.on_grant(skill.request.seq, "deny", "arm_1", 0.1)
    assert skill.phase == Phase.FAILED and "arm_1" in skill.failure_reason and skill.grants.denials == 1


def test_a_denied_transfer_is_asked_for_again():
    skill = started()
    skill.on_grant(skill.request.seq, "grant", "", 0.0)
    skill.plan.phase = Phase.TRANSFER  # as after a lift with a part in the claw
    skill.grants.begin(skill.plan.segment, Phase.TRANSFER, 1.0)
    first = skill.request.seq
    skill.on_grant(first, "deny", "arm_2", 1.1)
    assert skill.phase == Phase.TRANSFER and skill.request.seq == first + 1


def test_an_approach_kept_waiting_is_planned_again_from_where_the_part_has_gone():
    belt = (0.05, 0.0, 0.0)
    skill = started(belt)
    first = skill.request
    later = REPLAN_AFTER_S + 0.05
    skill.step(obs(SPEC.home_q, later), {7: part_at(0.0, later, belt)})
    assert skill.request.seq == first.seq + 1, "a fresh request for a fresh plan"
    assert not np.allclose(skill.request.q_to, first.q_to), "aimed where the part is now"


def transferring(at_s: float = 1.0) -> PickPlaceSkill:
    """A skill holding a part away from home, asking for its transfer at `at_s`."""
    skill = started()
    skill.on_grant(skill.request.seq, "grant", "", 0.0)
    skill.plan.q_cmd = skill.plan.segment.q_end.copy()  # at the hover pose, as after the grasp and lift
    away = skill.geometry.segment(skill.plan.q_cmd, np.asarray(SPEC.home_q) + 0.4, at_s, 0.5)
    skill.grants.begin(away, Phase.TRANSFER, at_s)
    return skill


def test_a_transfer_kept_out_makes_room_by_going_home_then_asks_again_from_there():
    skill = transferring(at_s=1.0)
    place_q = skill.plan.segment.q_end.copy()
    skill.on_grant(skill.request.seq, "deny", "arm_0", 1.1)
    assert np.allclose(skill.request.q_to, place_q), "denied briefly: the same transfer asked again"
    skill.on_grant(skill.request.seq, "deny", "arm_0", 1.0 + skill.timing.detour_after_s)
    assert skill.grants.detours == 0, (
        "asked 2 s ago, but denied for less: a move held back (a fixture not ready) is no blockade"
    )
    skill.on_grant(skill.request.seq, "deny", "arm_0", 1.1 + skill.timing.detour_after_s)
    detoured = skill.grants.detours == 1 and np.allclose(skill.request.q_to, SPEC.home_q)
    assert detoured, "kept out: home first, part in hand"
    skill.on_grant(skill.request.seq, "grant", "", 3.1)
    home_by = skill.plan.plan_end_s
    skill.step(obs(SPEC.home_q, home_by + 0.01), {})
    assert skill.phase == Phase.TRANSFER and np.allclose(skill.request.q_from, SPEC.home_q)
    assert np.allclose(skill.request.q_to, place_q), "then the transfer again, from home"


def test_an_arm_left_idle_away_from_home_goes_home_and_one_at_home_stays():
    skill = PickPlaceSkill(SPEC, BASE, grants_required=True)  # as a controller restarted with its arm mid-task
    away = np.asarray(SPEC.home_q) + 0.3
    assert skill.step(obs(away, 5.0), {}) == [] and skill.request is None
    skill.step(obs(away, 5.0 + skill.timing.clear_after_s / 2), {})
    assert skill.request is None, "a new task may still come: not yet"
    skill.step(obs(away, 5.0 + skill.timing.clear_after_s), {})
    assert skill.phase == Phase.HOME and skill.job is None and np.allclose(skill.request.q_to, SPEC.home_q)
    at_home = PickPlaceSkill(SPEC, BASE, grants_required=True)
    for k in range(5):
        at_home.step(obs(SPEC.home_q, k * 1.0), {})
    assert at_home.phase == Phase.IDLE and at_home.request is None


def test_a_request_carries_the_local_stage_that_follows_it_without_a_grant():
    skill = started()
    request = skill.request
    t = skill.timing
    assert len(request.then_q) == 4 and request.then_after_s[:3] == (
        t.descend_s,
        t.descend_s + t.close_s,
        t.descend_s + t.close_s + t.lift_s,
    )
    assert request.then_after_s[3] > request.then_after_s[2], "held a little longer: the grasp may start late"
    # the base stands on z = 0
    z = [skill.km.frame_pose(skill.km.full_q(np.asarray(q)))[2, 3] for q in (request.q_to, *request.then_q)]
    assert z[1] < z[0] - 0.05 and z[3] > z[2] + 0.05, "down from the hover to the part, then lifted"
    moving = transferring()
    place = moving.request
    assert len(place.then_q) == 4 and np.allclose(place.then_q[0], place.then_q[1]), (
        "lowered, held while the claw opens"
    )
    tool = [(BASE @ moving.km.frame_pose(moving.km.full_q(np.asarray(q))))[:3, 3] for q in place.then_q]
    assert np.allclose(tool[0][:2], moving.job.place_xyz[:2], atol=0.005), "lowered onto the place"
    assert tool[2][2] > tool[0][2] + 0.05, "and back up"


def test_an_arm_on_its_way_home_may_take_the_next_task_and_approaches_from_where_it_is():
    skill = PickPlaceSkill(SPEC, BASE, grants_required=True)
    away = np.asarray(SPEC.home_q) + 0.3
    skill.step(obs(away, 0.0), {})
    skill.step(obs(away, skill.timing.clear_after_s), {})  # an idle arm away from home sets off home
    assert skill.phase == Phase.HOME and skill.active and skill.available
    assert not started().available, "an arm at work is not available"
    on_the_way = (np.asarray(SPEC.home_q) + away) / 2
    task = PickPlaceJob(7, 0.08, (0.3, -0.55, 0.04), (0.0, 0.0, 0.0))
    skill.start(task, obs(on_the_way, 2.0), part_at(0.0))
    assert skill.phase == Phase.APPROACH and np.allclose(skill.request.q_from, on_the_way), (
        "home given up for the approach"
    )


def test_a_transfer_told_to_stand_by_waits_beside_the_place_then_asks_to_place_from_there():
    skill = transferring(at_s=1.0)
    place_q = skill.plan.segment.q_end.copy()
    skill.on_grant(skill.request.seq, "standby", "", 1.1)
    assert skill.phase == Phase.STANDBY and skill.grants.standbys == 1 and skill.request is not None, (
        "the move beside the place is asked for"
    )
    standby_q = np.asarray(skill.request.q_to)
    tool = lambda q: (BASE @ skill.km.frame_pose(skill.km.full_q(np.asarray(q))))[:3, 3]  # noqa: E731
    to_base = lambda q: np.linalg.norm(tool(q)[:2] - BASE[:2, 3])  # noqa: E731
    assert to_base(standby_q) < to_base(place_q) and tool(standby_q)[2] > tool(place_q)[2], (
        "nearer its own base, and higher"
    )
    skill.on_grant(skill.request.seq, "grant", "", 1.2)
    there = skill.plan.plan_end_s
    skill.step(obs(standby_q, there + 0.01), {})
    assert (
        skill.phase == Phase.TRANSFER
        and np.allclose(skill.request.q_from, standby_q)
        and np.allclose(skill.request.q_to, place_q)
    )
    asked = skill.request.seq
    skill.on_grant(asked, "standby", "", there + 0.1)
    assert skill.phase == Phase.TRANSFER and skill.grants.standbys == 1 and skill.request.seq == asked + 1, (
        "once a task: asked again"
    )


def test_a_stand_by_move_that_is_denied_asks_for_the_transfer_from_where_the_arm_is():
    skill = transferring(at_s=1.0)
    place_q, here = skill.plan.segment.q_end.copy(), skill.plan.q_cmd.copy()
    skill.on_grant(skill.request.seq, "standby", "", 1.1)
    skill.on_grant(skill.request.seq, "deny", "arm_0", 1.2)
    assert (
        skill.phase == Phase.TRANSFER
        and np.allclose(skill.request.q_from, here)
        and np.allclose(skill.request.q_to, place_q)
    )


def test_an_arm_released_from_an_estop_after_letting_its_part_go_goes_home_before_it_is_done():
    """A place the e-stop cut short once the claw had opened ends as it would have: home (asked for, from where the
    arm stands), then done. Left at the bin's low pose, the next approach swung the base joint faster than its
    drive follows, and the tracker aborted it off its path at every try."""
    skill = started()
    skill.on_grant(skill.request.seq, "grant", "", 0.0)
    skill.outbox.take(0.0, watched=False)  # the approach and the claw's goals went out long before
    at_bin = np.asarray(SPEC.home_q, float) + [-2.0, 0.6, -0.5, 0.0, -0.2, 0.0]
    skill.plan.phase, skill.estop.stopped_in = Phase.RELEASE, Phase.RELEASE  # as after an e-stop ended the release
    held = ArmObservation(5.0, at_bin, np.zeros(6), np.array(SPEC.gripper_open), held=True)
    assert skill.step(held, {}) == [] and skill.phase == Phase.RELEASE, "held: nothing sent"
    skill.step(obs(at_bin, 5.1), {})
    assert skill.phase == Phase.HOME and skill.request is not None, "released: home, asked for first"
    assert np.allclose(skill.request.q_from, at_bin) and np.allclose(skill.request.q_to, SPEC.home_q)
    skill.on_grant(skill.request.seq, "grant", "", 5.2)
    (home,) = [g for g in skill.step(obs(at_bin, 5.2), {}) if isinstance(g, TrajectoryGoal)]
    assert np.allclose(home.positions[-1], SPEC.home_q)
    skill.step(obs(SPEC.home_q, skill.plan.plan_end_s + 0.01), {})
    assert skill.phase == Phase.DONE


def test_an_approach_the_plant_refuses_is_given_back_as_a_denial_not_a_failed_attempt():
    skill = started()
    skill.on_grant(skill.request.seq, "grant", "", 0.1, start_time_s=0.15)
    (move,) = [g for g in skill.step(obs(SPEC.home_q, 0.1), {7: part_at(0.0)}) if isinstance(g, TrajectoryGoal)]
    refused = ArmObservation(
        0.2, np.asarray(SPEC.home_q, float), np.zeros(len(SPEC.home_q)), np.array(SPEC.gripper_open),
        move.goal_id, "rejected", "safety: its path comes within 10 mm of arm_1",
    )  # fmt: skip
    skill.step(refused, {7: part_at(0.0)})
    assert skill.phase == Phase.FAILED and skill.failure.code == FailureCode.MOTION_DENIED
    assert "its path comes within 10 mm of arm_1" in skill.failure.reason
