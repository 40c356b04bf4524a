"""E-stop holds every arm within a tick; a stale command trips the watchdog; limits are clamped and counted."""

import time

import numpy as np

from fleet.bus.codec import encode
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmCommandMsg, EStop
from fleet.bus.session import BusEndpoints, open_session
from fleet.nodes.sim_server import SimServer
from fleet.physics.world import World
from scenes import load_scene


def settle_bus():
    time.sleep(0.05)


def test_estop_watchdog_and_clamping():
    world = World(load_scene("handover"))
    keys = Keys("e")
    with open_session(BusEndpoints()) as session:
        server = SimServer(world, session, keys, mode="realtime", watchdog_s=0.1, first_command_timeout_s=0.5)
        try:
            home = np.array(world.arms["arm_0"].spec.home_q)
            goal = home + 0.4
            goal[0] = 10.0  # beyond the shoulder's limit: clamped, counted
            session.put(keys.arm_cmd("arm_0"), encode(ArmCommandMsg("arm_0", 0, tuple(goal), (0.0,) * 6, 1.0)))
            settle_bus()
            server.run_ticks(5, speed=100.0)
            assert server.stats.clamped["arm_0"] >= 1
            moving = world.arms["arm_0"].qvel()
            assert np.abs(moving).max() > 0.05, "the arm moves towards its command"
            session.put(keys.estop, encode(EStop(True, "test")))
            settle_bus()
            server.run_ticks(1, speed=100.0)
            q0 = world.arms["arm_0"].qpos()
            server.run_ticks(30, speed=100.0)
            assert server.estop
            assert np.abs(world.arms["arm_0"].qpos() - q0).max() < 0.02, "held within a tick of the e-stop"
            session.put(keys.estop, encode(EStop(False, "test")))
            settle_bus()
            server.run_ticks(30, speed=100.0)
            assert not server.estop
            assert server.stats.watchdog_holds["arm_0"] > 0, "the last command went stale: held by the watchdog"
            assert server.stats.lost == ["arm_1"], "an arm that never answered at the start is lost, and held"
            assert world.arms["arm_1"].qvel().max() < 1e-3
        finally:
            server.close()
