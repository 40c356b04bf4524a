"""Trajectory and gripper goals over real Zenoh on loopback: a client session sends goals to a sim server's arms
and hears one result per goal with control_msgs' codes, and feedback in the arm's states."""

import time

import numpy as np
import pytest

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.goals import goal_message
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState, EStop, GoalResultMsg, TrajectoryGoalMsg
from fleet.bus.session import BusEndpoints, Inbox, free_loopback_port, loopback_endpoint, open_session
from fleet.nodes.sim_server import SimServer
from fleet.robot_tools.trials import trial_scene
from fleet.sim.world import World
from robots.joint_trajectory import GripperGoal, TrajectoryGoal, rest_to_rest
from scenes import load_scene

WAIT_S = 10.0


class Client:
    """A trajectory client on its own session, connected to the server's endpoint over TCP."""

    def __init__(self, session, server: SimServer, keys: Keys) -> None:
        self.session, self.server, self.keys = session, server, keys
        self.results, self.states = Inbox(), Inbox()
        self._subs = [
            session.declare_subscriber(keys.all_arms("result"), self.results),
            session.declare_subscriber(keys.all_arms("state"), self.states),
        ]
        self.heard: list[GoalResultMsg] = []
        self.feedback: list[ArmState] = []
        self.sent = 0

    def send(self, arm: str, goal) -> None:
        """Publish a goal and run the sim until it has taken it."""
        self.session.put(
            self.keys.arm_goal(arm), encode(goal if isinstance(goal, TrajectoryGoalMsg) else goal_message(arm, goal))
        )
        self.sent += 1
        self.run_until(lambda: self.server.stats.messages_in["goal"] >= self.sent, "the goal never arrived")

    def run_until(self, done, what: str, ticks: int = 1500) -> None:
        deadline = time.monotonic() + WAIT_S
        for _ in range(ticks):
            self.take()
            if done():
                return
            if time.monotonic() > deadline:
                break
            self.server.run_ticks(1)
            time.sleep(0.0005 if self.server.stats.messages_in["goal"] < self.sent else 0)
        raise AssertionError(what)

    def take(self) -> None:
        decoder, state_decoder = Decoder(GoalResultMsg, DropCounter()), Decoder(ArmState, DropCounter())
        self.heard += [decoder.decode(k, p) for k, p in self.results.drain()]
        self.feedback += [state_decoder.decode(k, p) for k, p in self.states.drain()]

    def result(self, goal_id: int) -> GoalResultMsg:
        self.run_until(lambda: any(r.goal_id == goal_id for r in self.heard), f"no result for goal {goal_id}")
        return next(r for r in self.heard if r.goal_id == goal_id)

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()


@pytest.fixture
def cell(request):
    scene = request.param if hasattr(request, "param") else "pick_cell"
    world = World(trial_scene("openclaw", 0) if scene == "pick_cell" else load_scene(scene))
    keys = Keys("tg")
    endpoint = loopback_endpoint(free_loopback_port())
    with (
        open_session(BusEndpoints(listen=(endpoint,))) as server_session,
        open_session(BusEndpoints(connect=(endpoint,))) as client_session,
    ):
        server = SimServer(world, server_session, keys, mode="lockstep", controllers=False)
        client = Client(client_session, server, keys)
        time.sleep(0.3)  # the two sessions find each other
        try:
            yield world, server, client
        finally:
            client.close()
            server.close()


def arm_q(world: World, arm: str = "arm_0") -> np.ndarray:
    a = world.arms[arm]
    return a.qpos()[: a.spec.arm_dof]


def test_a_trajectory_is_followed_within_tolerance_and_ends_successful_with_feedback_on_the_way(cell):
    world, server, client = cell
    spec = world.arms["arm_0"].spec
    home = np.asarray(spec.home_q, float)
    waypoints = [home + [0.3, -0.1, 0.1, 0.0, 0.0, 0.2], home + [0.6, 0.0, -0.1, 0.0, 0.1, 0.4]]
    goal = TrajectoryGoal(
        11,
        spec.arm_joints,
        (1.0, 2.0),
        tuple(map(tuple, waypoints)),
        ((0.3, 0.0, 0.0, 0.0, 0.05, 0.2), (0.0,) * 6),
        path_tolerance_rad=(0.1,),
        goal_tolerance_rad=(0.01,),
    )
    client.send("arm_0", goal)
    result = client.result(11)
    assert (result.status, result.code, result.kind) == ("succeeded", 0, "trajectory")
    assert np.abs(arm_q(world) - waypoints[-1]).max() < 0.01
    during = [s for s in client.feedback if s.goal_id == 11]
    assert len(during) >= 20, "feedback at the controllers' default rate (20 Hz) while the goal ran"
    errors = [np.abs(np.subtract(s.desired_q, s.q)).max() for s in during]
    assert max(errors) < 0.1, "followed within the path tolerance"
    server.run_ticks(10)
    time.sleep(0.05)
    client.take()
    assert client.feedback[-1].result_goal_id == 11 and client.feedback[-1].result_status == "succeeded"


def test_each_kind_of_invalid_goal_is_refused_with_its_code_and_reason_and_the_arm_holds(cell):
    world, server, client = cell
    spec = world.arms["arm_0"].spec
    home = tuple(spec.home_q)
    names = tuple(spec.arm_joints)
    bad = {
        21: (
            TrajectoryGoalMsg("arm_0", 21, (*names[:5], "elbow_2"), (1.0,), home),
            -2,
            "unknown joint names ['elbow_2']",
        ),
        22: (TrajectoryGoalMsg("arm_0", 22, names, (1.0, 0.5), home + home), -1, "strictly increasing"),
        23: (TrajectoryGoalMsg("arm_0", 23, names, (1.0,), (9.0, *home[1:])), -1, "beyond the limits of shoulder_pan"),
        24: (TrajectoryGoalMsg("arm_0", 24, names, (1.0,), (float("nan"), *home[1:])), -1, "NaN"),
        25: (TrajectoryGoalMsg("arm_0", 25, names, (1.0, 2.0), home), -1, "6 values for 2 points of 6 joints"),
    }
    before = arm_q(world).copy()
    for goal_id, (msg, code, words) in bad.items():
        client.send("arm_0", msg)
        result = client.result(goal_id)
        assert (result.status, result.code) == ("rejected", code) and words in result.reason, result
    server.run_ticks(50)
    assert np.abs(arm_q(world) - before).max() < 1e-3, "the arm held"
    assert server.drops.total == 0, "well-formed but invalid goals are refused, not dropped"


def test_a_new_goal_preempts_the_running_one(cell):
    world, server, client = cell
    spec = world.arms["arm_0"].spec
    home = np.asarray(spec.home_q, float)
    client.send("arm_0", rest_to_rest(31, spec.arm_joints, home + [0.8, 0, 0, 0, 0, 0], 3.0, None))
    server.run_ticks(50)
    client.send("arm_0", rest_to_rest(32, spec.arm_joints, home + [-0.3, 0, 0, 0, 0, 0], 1.0, None))
    first = client.result(31)
    assert first.status == "preempted" and "goal 32" in first.reason
    assert client.result(32).status == "succeeded"
    assert abs(arm_q(world)[0] - (home[0] - 0.3)) < 0.02


def test_an_arm_blocked_by_the_belt_ends_path_tolerance_violated_and_holds(cell):
    world, server, client = cell
    spec = world.arms["arm_0"].spec
    down = np.asarray(spec.home_q, float)
    down[1] = world.arms["arm_0"].joint_limits()[1][1]  # the shoulder swings the arm down through the belt
    client.send("arm_0", rest_to_rest(41, spec.arm_joints, down, 2.0, None, path_tolerance_rad=(0.1,)))
    result = client.result(41)
    assert (result.status, result.code) == ("aborted", -4) and "shoulder_lift" in result.reason
    held = arm_q(world).copy()
    server.run_ticks(50)
    assert np.abs(arm_q(world) - held).max() < 0.05 and abs(held[1] - down[1]) > 0.3


@pytest.mark.parametrize("cell", ["handover"], indirect=True)
def test_estop_aborts_every_active_goal_and_refuses_new_ones(cell):
    world, server, client = cell
    for i, arm in enumerate(("arm_0", "arm_1")):
        spec = world.arms[arm].spec
        client.send(
            arm, rest_to_rest(51 + i, spec.arm_joints, np.asarray(spec.home_q) + [0.6, 0, 0, 0, 0, 0], 3.0, None)
        )
    server.run_ticks(30)
    client.session.put(client.keys.estop, encode(EStop(True, "test")))
    client.run_until(lambda: server.controls.estop, "the e-stop never arrived")
    for goal_id in (51, 52):
        r = client.result(goal_id)
        assert (r.status, r.code, r.reason) == ("aborted", -6, "emergency stop")
    q = {a: arm_q(world, a).copy() for a in ("arm_0", "arm_1")}
    server.run_ticks(50)
    assert all(np.abs(arm_q(world, a) - q[a]).max() < 0.02 for a in q), "every arm holds"
    client.send(
        "arm_0",
        rest_to_rest(53, world.arms["arm_0"].spec.arm_joints, np.asarray(world.arms["arm_0"].spec.home_q), 1.0, None),
    )
    refused = client.result(53)
    assert refused.status == "rejected" and "emergency stop" in refused.reason


def test_a_gripper_goal_closing_on_nothing_ends_reached(cell):
    world, server, client = cell
    client.send("arm_0", GripperGoal(61, 0.0))
    result = client.result(61)
    assert (result.kind, result.status, result.reached, result.stalled) == ("gripper", "succeeded", True, False)
