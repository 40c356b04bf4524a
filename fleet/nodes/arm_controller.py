"""The arm controller process: runs the pick-and-place skill for one arm behind the bus.

It sees its arm only through `ArmState` messages and the parts through
`PartsState`, takes work from `Assignment`, and answers every state with a
command stamped with that state's tick. It never imports the simulator.

    python -m fleet.nodes.arm_controller --scene pick_cell --arm arm_0 --run demo --connect tcp/127.0.0.1:7447
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import time

import numpy as np
import zenoh

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmCommandMsg, ArmState, ArmStatus, Assignment, PartsState
from fleet.bus.session import BusEndpoints, Inbox, add_bus_arguments, open_session
from robots.frames import yaw_transform
from robots.registry import get_robot
from robots.skills.interface import ArmObservation, PartObservation, PickPlaceTask
from robots.skills.pick_place import PickPlaceSkill
from scenes.loader import load_scene

HEARTBEAT_TICKS = 10


def parts_from_message(msg: PartsState) -> dict[int, PartObservation]:
    """Part observations from the flattened parts message."""
    out = {}
    for i, pid in enumerate(msg.part_ids):
        size = tuple(msg.sizes_m[3 * i : 3 * i + 3])
        out[pid] = PartObservation(
            pid, np.array(msg.positions[3 * i : 3 * i + 3]), np.array(msg.quaternions_wxyz[4 * i : 4 * i + 4]),
            np.array(msg.velocities[3 * i : 3 * i + 3]), float(min(size[0], size[1])), float(size[2]), size,
        )
    return out


class ArmController:
    """One arm's bridge (skill state machine) and cerebellum (its joint targets) on the bus."""

    def __init__(self, session: zenoh.Session, keys: Keys, arm: str, scene_name: str, arms: int | None = None) -> None:
        scene = load_scene(scene_name, arms=arms)
        decl = next((a for a in scene.arms if a.name == arm), None)
        if decl is None:
            raise SystemExit(f"arm_controller: no arm {arm!r} in scene {scene.name}; arms: {', '.join(a.name for a in scene.arms)}")
        self.arm, self.keys, self.session = arm, keys, session
        self.spec = get_robot(decl.model)
        self.dt = 1.0 / scene.control_hz
        self.skill = PickPlaceSkill(self.spec, yaw_transform(decl.base.xyz, decl.base.yaw_rad))
        self.drops = DropCounter()
        self._decoders = {
            "state": Decoder(ArmState, self.drops), "parts": Decoder(PartsState, self.drops),
            "assign": Decoder(Assignment, self.drops),
        }
        self._inboxes = {"state": Inbox(), "parts": Inbox(), "assign": Inbox()}
        self._subs = [
            session.declare_subscriber(keys.arm_state(arm), self._inboxes["state"]),
            session.declare_subscriber(keys.parts, self._inboxes["parts"]),
            session.declare_subscriber(keys.arm_assign(arm), self._inboxes["assign"]),
        ]
        self._cmd_pub = session.declare_publisher(keys.arm_cmd(arm))
        self._status_pub = session.declare_publisher(keys.arm_status(arm))
        self.parts: dict[int, PartObservation] = {}
        self.pending: Assignment | None = None
        self.task_id: int | None = None
        self.hold_q: np.ndarray | None = None
        self.seq = 0

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        self._cmd_pub.undeclare()
        self._status_pub.undeclare()

    def _latest(self, name: str):
        latest = None
        for key, payload in self._inboxes[name].drain():
            msg = self._decoders[name].decode(key, payload)
            if msg is not None:
                latest = msg
        return latest

    def poll(self) -> bool:
        """Handle what arrived; answer the newest state if there is one. True when a command was sent."""
        assign = self._latest("assign")
        if assign is not None:
            self.pending = assign
        parts = self._latest("parts")
        if parts is not None:
            self.parts = parts_from_message(parts)
        state = self._latest("state")
        if state is None:
            return False
        n = self.spec.arm_dof
        obs = ArmObservation(state.sim_time_s, np.array(state.q), np.array(state.dq), np.array(state.gripper_q))
        if self.hold_q is None:
            self.hold_q = obs.q.copy()
        if self.pending is not None and not self.skill.active and self.pending.part_id in self.parts:
            a, self.pending = self.pending, None
            task = PickPlaceTask(a.part_id, a.surface_z_m, tuple(a.place_xyz), tuple(a.surface_velocity))
            self.task_id = a.task_id
            self.skill.start(task, obs, self.parts[a.part_id])
        if self.skill.active:
            cmd = self.skill.step(obs, self.parts, self.dt)
            q, dq, opening = cmd.q, cmd.dq, cmd.gripper_opening
            self.hold_q = q
        else:
            q, dq, opening = self.hold_q, np.zeros(n), 1.0
        self._cmd_pub.put(encode(ArmCommandMsg(self.arm, state.tick, tuple(map(float, q)), tuple(map(float, dq)), float(opening))))
        if state.tick % HEARTBEAT_TICKS == 0:
            self.seq += 1
            self._status_pub.put(encode(ArmStatus(self.arm, self.seq, state.sim_time_s, self.skill.phase.value, self.task_id, self.skill.progress)))
        return True


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fleet-arm-controller", description=__doc__.splitlines()[0])
    parser.add_argument("--scene", required=True)
    parser.add_argument("--arms", type=int, default=None)
    parser.add_argument("--arm", required=True)
    parser.add_argument("--run", required=True)
    add_bus_arguments(parser)
    args = parser.parse_args(argv)
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    parent = os.getppid()
    with open_session(BusEndpoints.from_args(args)) as session:
        controller = ArmController(session, Keys(args.run), args.arm, args.scene, args.arms)
        try:
            while not stop and os.getppid() == parent:
                if not controller.poll():
                    time.sleep(0.0002)
        except KeyboardInterrupt:
            pass
        finally:
            controller.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
