"""Realtime: a controller that falls silent mid-trajectory is stopped by the tracker's watchdog within its deadline
(not after running the trajectory out); one that never answers is lost at the start and its arm held."""

import numpy as np

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.goals import goal_message
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmState, ControllerStep, GoalResultMsg
from fleet.bus.session import BusEndpoints, Inbox, open_session
from fleet.nodes.sim_server import SimServer
from fleet.sim.world import World
from robots.joint_trajectory import rest_to_rest
from scenes import load_scene


def test_a_silent_controller_trips_the_watchdog_mid_trajectory_and_a_mute_one_is_lost():
    world = World(load_scene("handover"))
    keys = Keys("wd")
    spec = world.arms["arm_0"].spec
    target = np.asarray(spec.home_q, float) + [1.2, 0, 0, 0, 0, 0]
    with open_session(BusEndpoints()) as session:
        server = SimServer(world, session, keys, mode="realtime", watchdog_s=0.1, first_command_timeout_s=0.5)
        decoder = Decoder(ArmState, DropCounter())
        talking = {"on": True, "sent": False}

        def answer(sample) -> None:  # a minimal controller for arm_0: one 4 s goal, then an answer to every state
            state = decoder.decode(str(sample.key_expr), sample.payload.to_bytes())
            if state is None or not talking["on"]:
                return
            ids = ()
            if not talking["sent"]:
                session.put(
                    keys.arm_goal("arm_0"),
                    encode(goal_message("arm_0", rest_to_rest(1, spec.arm_joints, target, 4.0, None))),
                )
                talking["sent"], ids = True, (1,)
            session.put(keys.arm_step("arm_0"), encode(ControllerStep("arm_0", state.tick, state.tick + 5, ids)))

        results = Inbox()
        subs = [
            session.declare_subscriber(keys.arm_state("arm_0"), answer),
            session.declare_subscriber(keys.all_arms("result"), results),
        ]
        try:
            server.run_ticks(100, speed=2.0)
            assert server.stats.lost == ["arm_1"], "an arm whose controller never answered is lost, and held"
            assert np.abs(world.arms["arm_1"].qvel()).max() < 1e-3
            assert np.abs(world.arms["arm_0"].qvel()).max() > 0.05, "arm_0 follows its goal"
            talking["on"] = False
            silent_at = world.sim_time_s
            server.run_ticks(60, speed=2.0)
            decode = Decoder(GoalResultMsg, DropCounter())
            heard = [decode.decode(k, p) for k, p in results.drain()]
            stop = next(r for r in heard if r.goal_id == 1)
            assert stop.status == "aborted" and stop.reason.startswith("watchdog"), stop
            assert stop.sim_time_s - silent_at <= 0.05 + 0.1 + 0.02, (
                "stopped within one period plus the watchdog deadline"
            )
            assert server.stats.watchdog_holds["arm_0"] == 1
            q = world.arms["arm_0"].qpos()[:6]
            server.run_ticks(30, speed=2.0)
            assert np.abs(world.arms["arm_0"].qpos()[:6] - q).max() < 0.02, "held, not run out to the goal"
            assert abs(q[0] - target[0]) > 0.3
        finally:
            for sub in subs:
                sub.undeclare()
            server.close()
