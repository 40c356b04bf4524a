"""The sim server and a real arm controller process over Zenoh on loopback, in lockstep.

The controller picks a part off the conveyor into the bin through the bus alone
(trajectory goals to the sim's tracker); garbage on its answer key is counted, not
fatal; a killed controller is marked lost and its arm held while the run goes on,
also when it dies in the middle of a move.
"""

import os
import signal
import subprocess
import sys

import numpy as np
import pytest

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.messages import Assignment, LineEvent
from fleet.bus.session import BusEndpoints, Inbox, free_loopback_port, loopback_endpoint, open_session
from fleet.nodes.sim_server import SimServer
from fleet.robot_tools.trials import trial_scene
from fleet.sim.world import World
from scenes.shapes import WALL_M


def start_controller(endpoint: str) -> subprocess.Popen:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "fleet.nodes.arm_controller",
            "--scene",
            "pick_cell",
            "--arm",
            "arm_0",
            "--run",
            "t",
            "--connect",
            endpoint,
        ],
    )


@pytest.mark.parametrize("node", ["fleet.nodes.arm_controller", "fleet.nodes.coordinator_node"])
def test_controller_and_coordinator_processes_never_import_the_simulator(node):
    code = f"import sys, {node}; assert 'sapien' not in sys.modules"
    assert subprocess.run([sys.executable, "-c", code]).returncode == 0


def test_pick_over_the_bus_then_garbage_then_a_lost_controller():
    endpoint = loopback_endpoint(free_loopback_port())
    world = World(trial_scene("openclaw", 0))  # pick_cell with its feeder off: only the part we spawn
    keys = Keys("t")
    with open_session(BusEndpoints(listen=(endpoint,))) as session:
        server = SimServer(world, session, keys, mode="lockstep", lockstep_timeout_s=1.0)
        events = Inbox()
        events_sub = session.declare_subscriber(keys.events, events)
        proc = start_controller(endpoint)
        try:
            part_id = world.spawn_now("trial_parts")
            server.run_ticks(30)
            assert server.stats.lost == []
            station = world.scene_model.station("bin_0")
            session.put(
                keys.arm_assign("arm_0"),
                encode(
                    Assignment(
                        "arm_0",
                        1,
                        1,
                        part_id,
                        world.scene_model.conveyor.pose.xyz[2],
                        (station.pose.xyz[0], station.pose.xyz[1], station.pose.xyz[2] + WALL_M),
                        tuple(world.belt_velocity()),
                    )
                ),
            )
            for _ in range(25):
                session.put(keys.arm_step("arm_0"), os.urandom(24))
                server.run_ticks(50)
            server.run_ticks(250)
            decoder = Decoder(LineEvent, DropCounter())
            seen = [decoder.decode(k, p) for k, p in events.drain()]
            said = [(e.kind, e.part_id, e.detail) for e in seen]
            assert ("arrived", part_id, "trial_parts") in said
            assert ("at_station", part_id, "bin_0") in said  # it came to rest in the bin
            assert ("retired", part_id, "bin_0") in said  # and the bin, a sink, was cleared
            assert server.stats.lost == []
            assert server.drops.total >= 25
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(timeout=5)
            server.run_ticks(20)
            assert server.stats.lost == ["arm_0"]
            q_held = world.arms["arm_0"].qpos()
            server.run_ticks(20)
            assert abs(world.arms["arm_0"].qpos() - q_held).max() < 1e-3
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.wait(timeout=5)
            events_sub.undeclare()
            server.close()


def test_a_controller_killed_mid_trajectory_leaves_its_arm_held_within_a_period_not_at_the_trajectorys_end():
    endpoint = loopback_endpoint(free_loopback_port())
    world = World(trial_scene("openclaw", 0))
    keys = Keys("t")
    with open_session(BusEndpoints(listen=(endpoint,))) as session:
        server = SimServer(world, session, keys, mode="lockstep", lockstep_timeout_s=1.0)
        proc = start_controller(endpoint)
        try:
            part_id = world.spawn_now("trial_parts")
            server.run_ticks(30)
            station = world.scene_model.station("bin_0")
            session.put(
                keys.arm_assign("arm_0"),
                encode(
                    Assignment(
                        "arm_0",
                        1,
                        1,
                        part_id,
                        world.scene_model.conveyor.pose.xyz[2],
                        (station.pose.xyz[0], station.pose.xyz[1], station.pose.xyz[2] + WALL_M),
                        tuple(world.belt_velocity()),
                    )
                ),
            )
            tracker = server.tracked.trackers["arm_0"]
            for _ in range(800):  # until the arm is in the middle of a long move
                server.run_ticks(1)
                a = tracker.active
                if (
                    a is not None
                    and a.spline.t_end_s - world.sim_time_s > 0.5
                    and np.abs(world.arms["arm_0"].qvel()[:6]).max() > 0.3
                ):
                    break
            else:
                raise AssertionError("the arm never made a long move")
            end_q = a.spline.q_end.copy()
            os.kill(proc.pid, signal.SIGKILL)
            proc.wait(timeout=5)
            killed_at = world.sim_time_s
            server.run_ticks(40)
            assert server.stats.lost == ["arm_0"]
            last = server.tracked.trackers["arm_0"].last
            assert last.status.value == "aborted" and "lost" in last.reason
            assert last.time_s - killed_at <= 2 * 0.05 + 1e-9, "held at the controller's next due tick"
            q = world.arms["arm_0"].qpos()[:6]
            server.run_ticks(50)
            assert np.abs(world.arms["arm_0"].qpos()[:6] - q).max() < 0.02, "and it stays held"
            assert np.abs(q - end_q).max() > 0.1, "short of where the trajectory was going"
        finally:
            if proc.poll() is None:
                proc.kill()
            proc.wait(timeout=5)
            server.close()
