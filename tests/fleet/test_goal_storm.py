"""A process that is not the line's, logged in as arm_0 (the router lets it drive arm_0), sends arm_0 twenty
in-limit trajectory goals aimed into arm_1 while the line runs: the plant's safety layer refuses each that would
bring the arms together, with a reason, and the physics sees no contact between arms for the whole run."""

import numpy as np
import pytest

from coordinator.geometry import ArmGeometry, separation_m
from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.goals import goal_message
from fleet.bus.keys import Keys
from fleet.bus.messages import GoalResultMsg
from fleet.bus.session import Inbox, open_session
from fleet.run.launcher import Launcher, RunOptions
from robots.frames import yaw_transform
from robots.joint_trajectory import rest_to_rest
from robots.registry import get_robot
from robots.trajectory import JointSegment
from tests.fleet.test_run import assert_nothing_left

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out


def poses_into(scene, arm: str, other: str, count: int) -> list[np.ndarray]:
    """In-limit joint positions of `arm` that put it inside `other` standing at home."""
    geometry = {
        a.name: ArmGeometry(a.name, get_robot(a.model), yaw_transform(a.base.xyz, a.base.yaw_rad))
        for a in scene.arms
        if a.name in (arm, other)
    }
    me, them = geometry[arm], geometry[other]
    lower, upper = me.km.lower[me.km.arm_q_index], me.km.upper[me.km.arm_q_index]
    rng, found = np.random.default_rng(0), []
    while len(found) < count:
        q = rng.uniform(lower, upper)
        me.place(q)
        if separation_m(me, them) < 0.005:
            found.append(q)
    return found


def storm_goals(scene, names: tuple[str, ...]) -> list:
    """Twenty goals for arm_0 into arm_1, each as fast as arm_0's joints may go from where the last one ended."""
    spec = get_robot(scene.arms[0].model)
    km = ArmGeometry("arm_0", spec, np.eye(4)).km
    limit = km.velocity_limit[km.arm_q_index]
    goals, q_from = [], np.asarray(spec.home_q, float)
    for k, q in enumerate(poses_into(scene, "arm_0", "arm_1", 20)):
        duration = JointSegment.timed(q_from, q, 0.0, limit, 0.9, min_duration_s=1.0).duration_s
        goals.append(rest_to_rest(900_000 + k, names, q, duration, None))
        q_from = q
    return goals


def test_a_storm_of_goals_from_outside_brings_no_two_arms_together():
    # realtime at 3x: the storm goes out one goal a progress message (every 0.5 s of wall time, 1.5 s of sim time),
    # each timed to end about then, within the joints' speed limits
    options = RunOptions(scene="sorting_line", duration_s=36.0, seed=0, mode="realtime", speed=3.0)
    results: list[GoalResultMsg] = []
    with Launcher(options) as launcher:
        keys = Keys(options.run_id)
        names = tuple(get_robot(launcher.scene.arms[0].model).arm_joints)
        goals = [
            rest_to_rest(900_000 + k, names, q, 3.0, None)
            for k, q in enumerate(poses_into(launcher.scene, "arm_0", "arm_1", 20))
        ]
        # arm_0's own login: the router lets it drive arm_0, so only the plant stands between it and arm_1
        with open_session(launcher.client_endpoints("arm_0")) as session:
            inbox = Inbox()
            sub = session.declare_subscriber(keys.arm_result("arm_0"), inbox)
            sent: list[int] = []

            def storm(progress) -> None:
                if 1.0 < progress.sim_time_s < 34.0 and len(sent) < len(goals):
                    goal = goals[len(sent)]
                    session.put(keys.arm_goal("arm_0"), encode(goal_message("arm_0", goal)))
                    sent.append(goal.goal_id)

            launcher.on_progress = storm
            summary = launcher.run()
            decoder = Decoder(GoalResultMsg, DropCounter())
            results = [m for k, p in inbox.drain() if (m := decoder.decode(k, p)) is not None and m.goal_id >= 900_000]
            sub.undeclare()
    assert_nothing_left(summary, launcher.endpoint)
    assert len(sent) == 20, "every goal of the storm went out while the line ran"
    assert summary["inter_arm_contacts"] == 0, summary["contact_pairs"]
    refused = [r for r in results if r.status == "rejected" and r.reason.startswith("safety: its path comes within")]
    assert len(refused) >= 10, [r.reason for r in results]
    assert summary["safety_refused_goals"].get("separation", 0) >= len(refused)
