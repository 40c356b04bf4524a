"""The sim server: owns the physics world, publishes arm and part states each control tick, applies commands.

Each arm's latest valid command is held (zero-order hold). A command older than
the watchdog limit (sim time) makes the arm hold still; so does the e-stop.
Joint targets outside the limits are clamped and counted. In `lockstep` the
server waits each tick for every live controller's command to that tick; one
silent past the timeout is marked lost, its arm held, and the run goes on.
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, field

import numpy as np
import zenoh

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmCommandMsg, ArmState, EStop, PartsState
from fleet.bus.session import Inbox
from fleet.physics.world import World


@dataclass
class ArmLink:
    """The server's view of one arm's controller: its latest command and whether it is alive."""

    name: str
    last_cmd: ArmCommandMsg | None = None
    last_cmd_time_s: float = -np.inf
    lost: bool = False


@dataclass
class SimStats:
    clamped: Counter = field(default_factory=Counter)
    watchdog_holds: Counter = field(default_factory=Counter)
    lost: list[str] = field(default_factory=list)
    ticks: int = 0


class SimServer:
    """Runs a world behind the bus; call `run_ticks` (or `tick` repeatedly)."""

    def __init__(
        self,
        world: World,
        session: zenoh.Session,
        keys: Keys,
        *,
        mode: str = "lockstep",
        watchdog_s: float = 0.1,
        lockstep_timeout_s: float = 1.0,
        first_command_timeout_s: float = 30.0,
    ) -> None:
        if mode not in ("lockstep", "realtime"):
            raise ValueError(f"mode {mode!r}: valid modes are lockstep, realtime")
        self.world, self.session, self.keys, self.mode = world, session, keys, mode
        self.watchdog_s, self.lockstep_timeout_s = watchdog_s, lockstep_timeout_s
        self.first_command_timeout_s = first_command_timeout_s
        self.links = {name: ArmLink(name) for name in world.arms}
        self._limits = {name: arm.joint_limits() for name, arm in world.arms.items()}
        self.drops = DropCounter()
        self.stats = SimStats()
        self.estop = False
        self._cmd_decoder = Decoder(ArmCommandMsg, self.drops)
        self._estop_decoder = Decoder(EStop, self.drops)
        self._cmd_inbox, self._estop_inbox = Inbox(), Inbox()
        self._subs = [
            session.declare_subscriber(keys.all_arms("cmd"), self._cmd_inbox),
            session.declare_subscriber(keys.estop, self._estop_inbox),
        ]
        self._state_pubs = {name: session.declare_publisher(keys.arm_state(name)) for name in world.arms}
        self._parts_pub = session.declare_publisher(keys.parts)

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        for pub in [*self._state_pubs.values(), self._parts_pub]:
            pub.undeclare()

    # --- inputs ---------------------------------------------------------------------
    def _take_inputs(self) -> None:
        for key, payload in self._estop_inbox.drain():
            msg = self._estop_decoder.decode(key, payload)
            if msg is not None:
                self.estop = msg.engaged
        for key, payload in self._cmd_inbox.drain():
            msg = self._cmd_decoder.decode(key, payload)
            if msg is None:
                continue
            link = self.links.get(Keys.arm_of(key))
            if link is None or msg.arm != link.name:
                self.drops.drop(key, "command for an unknown arm or on another arm's key")
                continue
            n = self.world.arms[link.name].spec.arm_dof
            if len(msg.q) != n or len(msg.dq) != n or not np.all(np.isfinite(msg.q + msg.dq + (msg.gripper_opening,))):
                self.drops.drop(key, f"command with wrong length or non-finite values (arm has {n} joints)")
                continue
            if link.last_cmd is None or msg.tick >= link.last_cmd.tick:
                link.last_cmd, link.last_cmd_time_s = msg, self.world.sim_time_s

    def _wait_for_commands(self) -> None:
        """Lockstep: until every live arm answered this tick's state, or its timeout passed."""
        tick = self.world.tick
        first = tick == 0
        deadline = time.monotonic() + (self.first_command_timeout_s if first else self.lockstep_timeout_s)
        republish_at = time.monotonic() + 0.05
        while True:
            self._take_inputs()
            waiting = [l for l in self.links.values() if not l.lost and (l.last_cmd is None or l.last_cmd.tick < tick)]
            if not waiting:
                return
            if time.monotonic() > deadline:
                for link in waiting:
                    link.lost = True
                    self.stats.lost.append(link.name)
                return
            if time.monotonic() > republish_at:  # a controller that joined late, or a lost sample
                self.publish_state()
                republish_at = time.monotonic() + 0.05
            time.sleep(0.0001)

    # --- one tick -------------------------------------------------------------------
    def publish_state(self) -> None:
        w = self.world
        for name, arm in w.arms.items():
            q, dq, n = arm.qpos(), arm.qvel(), arm.spec.arm_dof
            tool = arm.tool_pose_world()
            msg = ArmState(
                name, w.tick, w.sim_time_s, tuple(q[:n].tolist()), tuple(dq[:n].tolist()), tuple(q[n:].tolist()),
                tuple(map(float, tool.p)), tuple(map(float, tool.q)),
            )
            self._state_pubs[name].put(encode(msg))
        parts = w.active_parts()
        self._parts_pub.put(encode(PartsState(
            w.tick, w.sim_time_s, tuple(p.part_id for p in parts), tuple(p.feeder for p in parts),
            tuple(p.type_index for p in parts),
            tuple(float(v) for p in parts for v in p.position), tuple(float(v) for p in parts for v in p.quaternion_wxyz),
            tuple(float(v) for p in parts for v in p.velocity),
            tuple(float(v) for p in parts for v in p.size_m),
        )))

    def _apply_commands(self) -> None:
        now = self.world.sim_time_s
        for name, link in self.links.items():
            arm = self.world.arms[name]
            n = arm.spec.arm_dof
            stale = link.last_cmd is None or now - link.last_cmd_time_s > self.watchdog_s + 1e-9
            if self.estop or link.lost or stale:
                if stale and not (self.estop or link.lost):
                    self.stats.watchdog_holds[name] += 1
                hold = arm.qpos()
                arm.set_targets(hold[:n], np.zeros(n), arm.drive_targets()[n:])
                continue
            cmd = link.last_cmd
            lower, upper = self._limits[name]
            q = np.asarray(cmd.q)
            clamped = np.clip(q, lower[:n], upper[:n])
            if np.any(clamped != q):
                self.stats.clamped[name] += 1
            arm.set_targets(clamped, np.asarray(cmd.dq), arm.spec.gripper_targets(cmd.gripper_opening))

    def tick(self) -> None:
        """Publish states, gather commands (waiting in lockstep), apply them, step physics."""
        self.publish_state()
        if self.mode == "lockstep":
            self._wait_for_commands()
        else:
            self._take_inputs()
        self._apply_commands()
        self.world.step()
        self.stats.ticks += 1

    def run_ticks(self, ticks: int, speed: float = 1.0) -> None:
        """Run `ticks` ticks; in realtime mode paced by the wall clock at `speed` x real time."""
        start_wall, start_sim = time.monotonic(), self.world.sim_time_s
        for _ in range(ticks):
            self.tick()
            if self.mode == "realtime":
                ahead = (self.world.sim_time_s - start_sim) / speed - (time.monotonic() - start_wall)
                if ahead > 0:
                    time.sleep(ahead)
