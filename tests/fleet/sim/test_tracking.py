"""Trackers over a real world: an e-stop stops an arm moving at its joints' speed limit where it is."""

import numpy as np
import pytest

from fleet.sim.tracking import TrackedArms
from fleet.sim.world import World
from robots.joint_trajectory import rest_to_rest
from robots.kinematics import KinematicModel
from robots.skills.pick_place import PickPlaceTiming
from robots.trajectory import JointSegment
from scenes import load_scene


@pytest.mark.parametrize("joint", range(6))
def test_an_estop_holds_an_arm_stopped_mid_move_at_the_skills_top_speed(joint):
    world = World(load_scene("pick_cell"))
    tracked = TrackedArms(world)
    arm = world.arms["arm_0"]
    km, n = KinematicModel(arm.spec), arm.spec.arm_dof
    start = arm.qpos()[:n]
    end = start.copy()
    end[joint] = np.clip(start[joint] + 1.2, km.lower[km.arm_q_index][joint], km.upper[km.arm_q_index][joint])
    move = JointSegment.timed(start, end, 0.0, km.velocity_limit[km.arm_q_index], PickPlaceTiming().transfer_speed)
    tracked.submit("arm_0", rest_to_rest(1, tuple(arm.spec.arm_joints), end, move.duration_s, world.sim_time_s))
    while world.sim_time_s < move.duration_s / 2:  # the joint at its peak speed
        tracked.apply(), world.step(), tracked.update()
    assert abs(arm.qvel()[joint]) > 0.5 * km.velocity_limit[km.arm_q_index][joint]
    results = tracked.set_estop(True)
    assert [r.status.value for r in results["arm_0"]] == ["aborted"]
    stopped_at = arm.qpos()[:n]
    seen = []
    for _ in range(int(1.0 / world.control_dt_s)):
        tracked.apply(), world.step(), tracked.update()
        seen.append(arm.qpos()[:n])
    settled = np.array(seen)[int(0.1 / world.control_dt_s) :]
    assert np.abs(settled - stopped_at).max() < 0.01, "the arm holds where the e-stop found it"
