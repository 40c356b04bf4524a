"""The sim server: owns the physics world, publishes arm and part states each control tick, applies commands.

Each arm's latest valid command is held (zero-order hold). A command older than
the watchdog limit (sim time) makes the arm hold still; so does the e-stop.
Joint targets outside the limits are clamped and counted. In `lockstep` the
server waits each tick for every live controller's command to that tick; one
silent past the timeout is marked lost, its arm held, and the run goes on; a
lost controller that answers again rejoins. With a coordinator in lockstep, every
`coord_period_ticks` the server also waits for the coordinator's `CoordTick`, so
its decisions land on the same tick in every run.

    python -m fleet.nodes.sim_server --scene assembly_line --run demo --listen tcp/127.0.0.1:7447 --duration 60
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import time
from collections import Counter, deque
from dataclasses import dataclass, field

import numpy as np
import zenoh

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.messages import ArmCommandMsg, CoordTick, EStop, LineEvent, LineView, SimControl, SimStatus
from fleet.bus.session import BusEndpoints, Inbox, add_bus_arguments, make_config, open_listening_session
from fleet.line_watch import LineWatcher
from fleet.nodes.lifecycle import StopFlag, add_scene_arguments, load_node_scene, write_report, write_text_atomically
from fleet.physics.world import PartInfo, World
from fleet.world_messages import arm_state, parts_state

COORD_RATE_HZ = 10.0
STATUS_PERIOD_S = 0.25  # wall seconds between `SimStatus` messages
HOLD_STILL_RAD_PER_S = 0.02  # a held arm slower than this on every joint is at rest: its hold position is latched
VIEW_RATE_HZ = 25.0  # sim-time rate of the monitors' `LineView`
IDLE_SKILLS = ("idle", "done", "failed")


@dataclass
class ArmLink:
    """The server's view of one arm's controller: its latest command and whether it is alive."""

    name: str
    last_cmd: ArmCommandMsg | None = None
    last_cmd_time_s: float = -np.inf
    lost: bool = False
    hold_q: np.ndarray | None = None  # where a held arm came to rest (kept until released)


@dataclass
class SimStats:
    """What the server counts over a run; `report` turns it into the run summary's sim part."""

    clamped: Counter = field(default_factory=Counter)
    watchdog_holds: Counter = field(default_factory=Counter)
    lost: list[str] = field(default_factory=list)
    rejoined: list[str] = field(default_factory=list)
    ticks: int = 0
    contact_ticks: int = 0
    contact_pairs: set = field(default_factory=set)
    round_trip_ms: list[float] = field(default_factory=list)
    coordinator_lost: bool = False
    wall_s: Counter = field(default_factory=Counter)  # where the server's wall time went, by stage
    busy_ticks: Counter = field(default_factory=Counter)  # ticks each arm's applied command came from a running skill
    recent_round_trip_ms: deque = field(default_factory=lambda: deque(maxlen=1000))
    last_contact_pairs: tuple[str, ...] = ()
    last_contact_s: float = -1.0


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
        coordinator: bool = False,
        count_contacts: bool = True,
        stop: StopFlag | None = None,
        speed: float = 1.0,
    ) -> None:
        if mode not in ("lockstep", "realtime"):
            raise ValueError(f"mode {mode!r}: valid modes are lockstep, realtime")
        self.world, self.session, self.keys, self.mode = world, session, keys, mode
        self.watchdog_s, self.lockstep_timeout_s = watchdog_s, lockstep_timeout_s
        self.first_command_timeout_s = first_command_timeout_s
        self.stop = stop
        self.links = {name: ArmLink(name) for name in world.arms}
        self._limits = {name: arm.joint_limits() for name, arm in world.arms.items()}
        self.drops = DropCounter()
        self.stats = SimStats()
        self.estop = False
        self.paused = False
        self.speed = speed
        self._status_at = 0.0
        self._control_decoder = Decoder(SimControl, self.drops)
        self._cmd_decoder = Decoder(ArmCommandMsg, self.drops)
        self._estop_decoder = Decoder(EStop, self.drops)
        self._coord_decoder = Decoder(CoordTick, self.drops)
        self._cmd_inbox = Inbox()
        self._estop_inbox, self._coord_inbox = Inbox(wake=self._cmd_inbox.wake), Inbox(wake=self._cmd_inbox.wake)
        self._control_inbox = Inbox(wake=self._cmd_inbox.wake)
        self._subs = [
            session.declare_subscriber(keys.all_arms("cmd"), self._cmd_inbox),
            session.declare_subscriber(keys.estop, self._estop_inbox),
            session.declare_subscriber(keys.coord("tick"), self._coord_inbox),
            session.declare_subscriber(keys.control, self._control_inbox),
        ]
        scene_json = world.scene_model.model_dump_json().encode()
        self._scene_queryable = session.declare_queryable(keys.scene, lambda query: query.reply(keys.scene, scene_json))
        self._status_pub = session.declare_publisher(keys.sim_status)
        self._view_pub = session.declare_publisher(keys.view)
        self.view_every_ticks = max(1, round(world.scene_model.control_hz / VIEW_RATE_HZ))
        self._state_pubs = {name: session.declare_publisher(keys.arm_state(name)) for name in world.arms}
        self._parts_pub = session.declare_publisher(keys.parts)
        self._events_pub = session.declare_publisher(keys.events)
        self.watcher = LineWatcher(world.scene_model)
        self.events_published = Counter()
        self.count_contacts = count_contacts
        self.coordinator = coordinator
        self.coord_period_ticks = max(1, round(world.scene_model.control_hz / COORD_RATE_HZ))
        self._coord_tick = -1
        self.assign_seqs = {name: 0 for name in world.arms}
        self._published_at: dict[int, float] = {}

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        self._scene_queryable.undeclare()
        for pub in [*self._state_pubs.values(), self._parts_pub, self._events_pub, self._status_pub, self._view_pub]:
            pub.undeclare()

    # --- inputs ---------------------------------------------------------------------
    def _take_inputs(self) -> None:
        for key, payload in self._estop_inbox.drain():
            msg = self._estop_decoder.decode(key, payload)
            if msg is not None:
                self.estop = msg.engaged
        for key, payload in self._control_inbox.drain():
            msg = self._control_decoder.decode(key, payload)
            if msg is None:
                continue
            if msg.speed is not None and not (math.isfinite(msg.speed) and 0.01 <= msg.speed <= 100.0):
                self.drops.drop(key, "speed factor outside 0.01..100")
                continue
            if msg.paused is not None:
                self.paused = msg.paused
            if msg.speed is not None:
                self.speed = msg.speed
        for key, payload in self._cmd_inbox.drain():
            msg = self._cmd_decoder.decode(key, payload)
            if msg is None:
                continue
            link = self.links.get(Keys.arm_of(key))
            if link is None or msg.arm != link.name:
                self.drops.drop(key, "command for an unknown arm or on another arm's key")
                continue
            n = self.world.arms[link.name].spec.arm_dof
            values = msg.q + msg.dq + msg.request_q_to + (msg.gripper_opening, msg.request_duration_s)
            if len(msg.q) != n or len(msg.dq) != n or len(msg.request_q_to) not in (0, n) or not np.all(np.isfinite(values)):
                self.drops.drop(key, f"command with wrong length or non-finite values (arm has {n} joints)")
                continue
            if link.last_cmd is None or msg.tick >= link.last_cmd.tick:
                link.last_cmd, link.last_cmd_time_s = msg, self.world.sim_time_s
                sent = self._published_at.get(msg.tick)
                if sent is not None:
                    rtt_ms = (time.monotonic() - sent) * 1e3
                    self.stats.round_trip_ms.append(rtt_ms)
                    self.stats.recent_round_trip_ms.append(rtt_ms)
                if link.lost and msg.tick >= self.world.tick - 1:
                    link.lost = False
                    self.stats.rejoined.append(link.name)
        for key, payload in self._coord_inbox.drain():
            msg = self._coord_decoder.decode(key, payload)
            if msg is None:
                continue
            if len(msg.assign_seqs) != len(self.links):
                self.drops.drop(key, f"coordinator tick with {len(msg.assign_seqs)} arms, the scene has {len(self.links)}")
                continue
            self._coord_tick = max(self._coord_tick, msg.tick)
            if self.mode != "lockstep":
                continue  # realtime: controllers act on assignments as they arrive
            for name, seq in zip(self.links, msg.assign_seqs):
                self.assign_seqs[name] = max(self.assign_seqs[name], seq)

    def _wait_for_commands(self) -> None:
        """Lockstep: until every live arm answered this tick's state, or its timeout passed."""
        tick = self.world.tick
        first = tick == 0
        deadline = time.monotonic() + (self.first_command_timeout_s if first else self.lockstep_timeout_s)
        republish_at = time.monotonic() + 0.05
        coord_tick = tick % self.coord_period_ticks == 0 if self.mode == "lockstep" else tick == 0
        want_coord = self.coordinator and not self.stats.coordinator_lost and coord_tick
        while True:
            self._take_inputs()
            waiting = [l for l in self.links.values() if not l.lost and (l.last_cmd is None or l.last_cmd.tick < tick)]
            coord_waiting = want_coord and self._coord_tick < tick
            if not waiting and not coord_waiting:
                return
            if self.stop is not None and self.stop.should_stop():
                return
            if time.monotonic() > deadline:
                for link in waiting:
                    link.lost = True
                    self.stats.lost.append(link.name)
                if coord_waiting:
                    self.stats.coordinator_lost = True
                return
            if time.monotonic() > republish_at:  # a controller that joined late, or a lost sample
                self.publish_state()
                republish_at = time.monotonic() + 0.05
            self._cmd_inbox.wait(0.01)

    # --- one tick -------------------------------------------------------------------
    def _stale(self, link: ArmLink) -> bool:
        """No command, or the newest is older than the watchdog limit (sim time)."""
        return link.last_cmd is None or self.world.sim_time_s - link.last_cmd_time_s > self.watchdog_s + 1e-9

    def _held(self, link: ArmLink) -> bool:
        return self.estop or link.lost or self._stale(link)

    def publish_events(self, parts: list[PartInfo]) -> bool:
        """This tick's line events (parts arrived, resting at a station, lost, retired), before the states.
        True when some part left the stage (lost or retired), so `parts` is out of date."""
        left = False
        for e in self.watcher.update(self.world, parts):
            self.events_published[e.kind] += 1
            self._events_pub.put(encode(LineEvent(e.kind, e.part_id, e.tick, e.detail, e.type_index)))
            left = left or e.kind in ("lost", "retired")
        return left

    def publish_state(self, parts: list[PartInfo] | None = None) -> None:
        """Every arm's state, then the parts (`parts`: the tick's active parts, if already at hand)."""
        w = self.world
        self._published_at[w.tick] = time.monotonic()
        self._published_at.pop(w.tick - 256, None)
        states = []
        for name in w.arms:
            link = self.links[name]
            cmd = link.last_cmd
            msg = arm_state(
                w, name, held=self._held(link), lost=link.lost,
                task_id=cmd.task_id if cmd else None, skill=cmd.skill if cmd else "idle", progress=cmd.progress if cmd else 0.0,
                assign_seq=self.assign_seqs[name] if self.coordinator and self.mode == "lockstep" else -1, failure=cmd.failure if cmd else "",
                request_seq=cmd.request_seq if cmd else 0, request_q_to=cmd.request_q_to if cmd else (),
                request_duration_s=cmd.request_duration_s if cmd else 0.0,
            )
            self._state_pubs[name].put(encode(msg))
            states.append(msg)
        parts = w.active_parts() if parts is None else parts
        parts_msg = parts_state(w, parts, sum(self.events_published.values()))
        self._parts_pub.put(encode(parts_msg))
        if w.tick % self.view_every_ticks == 0 and self._view_pub.matching_status.matching:  # built only while watched
            self._view_pub.put(encode(LineView(w.tick, w.sim_time_s, tuple(states), parts_msg)))

    def _apply_commands(self) -> None:
        for name, link in self.links.items():
            arm = self.world.arms[name]
            n = arm.spec.arm_dof
            if self._held(link):
                if not (self.estop or link.lost):  # held for no other reason than a stale command
                    self.stats.watchdog_holds[name] += 1
                if link.hold_q is None or np.abs(arm.qvel()[:n]).max() > HOLD_STILL_RAD_PER_S:
                    link.hold_q = arm.qpos()[:n].copy()  # braking: hold where it is; once still, latched (no creep)
                arm.set_targets(link.hold_q, np.zeros(n), arm.drive_targets()[n:])
                continue
            link.hold_q = None
            cmd = link.last_cmd
            if cmd.skill not in IDLE_SKILLS:
                self.stats.busy_ticks[name] += 1
            lower, upper = self._limits[name]
            q = np.asarray(cmd.q)
            clamped = np.clip(q, lower[:n], upper[:n])
            if np.any(clamped != q):
                self.stats.clamped[name] += 1
            arm.set_targets(clamped, np.asarray(cmd.dq), arm.spec.gripper_targets(cmd.gripper_opening))

    def tick(self) -> None:
        """Publish events and states, gather commands (waiting in lockstep), apply them, step physics."""
        clock = self.stats.wall_s
        t0 = time.perf_counter()
        parts = self.world.active_parts()
        if self.publish_events(parts):
            parts = self.world.active_parts()  # parts lost or retired just now are off the stage
        self.publish_state(parts)
        t1 = time.perf_counter()
        if self.mode == "lockstep" or self.world.tick == 0:  # realtime too waits once, for every process to start
            self._wait_for_commands()
        else:
            self._take_inputs()
        t2 = time.perf_counter()
        self._apply_commands()
        self.world.step()
        t3 = time.perf_counter()
        self.stats.ticks += 1
        if self.count_contacts:
            pairs = self.world.inter_arm_contacts()
            if pairs:
                self.stats.contact_ticks += 1
                self.stats.contact_pairs.update(pairs)
                self.stats.last_contact_pairs = tuple(sorted("-".join(p) for p in pairs))
                self.stats.last_contact_s = self.world.sim_time_s
        t4 = time.perf_counter()
        clock["publish"] += t1 - t0
        clock["wait" if self.stats.ticks > 1 else "startup"] += t2 - t1  # tick 0 waits for every process to start
        clock["physics"] += t3 - t2
        clock["contacts"] += t4 - t3

    def run_ticks(self, ticks: int, speed: float | None = None, stop: StopFlag | None = None) -> None:
        """Run `ticks` ticks (or until `stop`); in realtime mode paced by the wall clock at the speed factor.

        A pause (`SimControl`) stops the clock between ticks; the pacing restarts from where it stood."""
        stop = stop or self.stop
        if speed is not None:
            self.speed = speed
        start_wall, start_sim, speed_then = time.monotonic(), self.world.sim_time_s, self.speed
        done = 0
        while done < ticks:
            if stop is not None and stop.should_stop():
                return
            self.publish_status()
            if self.paused:
                self._take_inputs()
                self._cmd_inbox.wait(0.05)
                start_wall, start_sim = time.monotonic(), self.world.sim_time_s
                continue
            self.tick()
            done += 1
            if stop is not None and stop.should_stop():
                return
            if self.stats.coordinator_lost and self.mode == "lockstep":
                return  # its decisions would never be announced again: end the run rather than stall it
            if self.mode == "realtime":
                if self.world.tick == 1 or self.speed != speed_then:  # the clock starts once every process answered tick 0
                    start_wall, start_sim, speed_then = time.monotonic(), self.world.sim_time_s, self.speed
                ahead = (self.world.sim_time_s - start_sim) / self.speed - (time.monotonic() - start_wall)
                if ahead > 0:
                    time.sleep(ahead)
                    self.stats.wall_s["pacing"] += ahead
        self.publish_status(force=True)

    def publish_status(self, force: bool = False) -> None:
        """The clock's settings and running figures, every `STATUS_PERIOD_S` of wall time."""
        now = time.monotonic()
        if not force and now - self._status_at < STATUS_PERIOD_S:
            return
        self._status_at = now
        st, ticks = self.stats, max(self.stats.ticks, 1)
        recent = st.recent_round_trip_ms
        self._status_pub.put(encode(SimStatus(
            self.world.tick, self.world.sim_time_s, self.mode, self.paused, self.estop, self.speed,
            tuple(st.busy_ticks[a] / ticks for a in self.links),
            float(np.percentile(np.asarray(recent), 99)) if recent else 0.0,
            st.contact_ticks, st.last_contact_pairs, st.last_contact_s,
            tuple(l.name for l in self.links.values() if l.lost), self.drops.total,
        )))

    def report(self) -> dict:
        """The sim's part of the run summary."""
        rtt = np.asarray(self.stats.round_trip_ms)
        return {
            "ticks": self.stats.ticks,
            "sim_seconds": round(self.world.sim_time_s, 6),
            "parts_spawned": sum(c.spawned for c in self.world.feeders),
            "feeder_full_skips": sum(c.skipped_full for c in self.world.feeders),
            "events": dict(sorted(self.events_published.items())),
            "utilisation": {a: round(self.stats.busy_ticks[a] / self.stats.ticks, 4) if self.stats.ticks else 0.0 for a in self.links},
            "inter_arm_contacts": self.stats.contact_ticks,
            "contact_pairs": sorted("-".join(p) for p in self.stats.contact_pairs),
            "latency_p50_ms": round(float(np.percentile(rtt, 50)), 3) if rtt.size else None,
            "latency_p99_ms": round(float(np.percentile(rtt, 99)), 3) if rtt.size else None,
            "dropped_messages": self.drops.total,
            "clamped_commands": dict(self.stats.clamped),
            "watchdog_holds": dict(self.stats.watchdog_holds),
            "arms_lost": list(self.stats.lost),
            "arms_rejoined": list(self.stats.rejoined),
            "coordinator_lost": self.stats.coordinator_lost,
            "wall_s_by_stage": {k: round(v, 3) for k, v in self.stats.wall_s.items()},
            "loop_wall_seconds": round(sum(v for k, v in self.stats.wall_s.items() if k != "startup"), 3),
        }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="fleet-sim-server", description=__doc__.splitlines()[0])
    add_scene_arguments(parser)
    parser.add_argument("--duration", type=float, default=120.0, help="sim seconds")
    parser.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep")
    parser.add_argument("--speed", type=float, default=1.0)
    parser.add_argument("--seed", type=int, default=None)
    parser.add_argument("--coordinator", action="store_true", help="wait for the coordinator's tick (lockstep: every 10 Hz; realtime: at start)")
    parser.add_argument("--lockstep-timeout", type=float, default=1.0, help="wall seconds before a silent controller is lost")
    parser.add_argument("--report", help="write the end-of-run figures to this JSON file")
    parser.add_argument("--endpoint-file", help="listen on a free loopback port and write its endpoint to this file")
    add_bus_arguments(parser)
    args = parser.parse_args(argv)
    stop = StopFlag()
    scene = load_node_scene(args, "sim_server")
    if scene is None:
        return 2
    if args.seed is not None:
        scene = scene.model_copy(update={"seed": args.seed})
    world = World(scene)
    ticks = math.ceil(args.duration * scene.control_hz - 1e-9)
    endpoints = BusEndpoints.from_args(args)
    if args.endpoint_file:
        session, endpoint = open_listening_session(endpoints)
        write_text_atomically(args.endpoint_file, endpoint)
    else:
        session = zenoh.open(make_config(endpoints))
    with contextlib.closing(session):
        server = SimServer(
            world, session, Keys(args.run), mode=args.mode, coordinator=args.coordinator,
            lockstep_timeout_s=args.lockstep_timeout, stop=stop, speed=args.speed,
        )
        try:
            server.run_ticks(ticks)
        finally:
            lost = "the coordinator did not answer within the lockstep timeout" if server.stats.coordinator_lost and args.mode == "lockstep" else ""
            report = server.report() | {"stopped_by": stop.reason or lost or "duration"}
            server.close()
            write_report(args.report, report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
