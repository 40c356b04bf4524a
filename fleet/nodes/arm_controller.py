"""The arm controller process: runs the pick-and-place skill for one arm behind the bus, at its own rate.

It sees its arm only through `ArmState` messages (with the tracker's feedback) and
the parts through `PartsState`, takes work from `Assignment`, and drives the arm
with trajectory and gripper goals on the arm's `goal` key, which the arm's tracker
(in the sim, or a real arm's driver) follows. It answers every state it gets with a
`ControllerStep` naming the goals it just sent and when it wants its next state
(`--rate-hz`, 20 by default). A state naming an assignment this controller has not
received yet (`assign_seq`, lockstep) waits for it, so work starts on the same tick
in every run. It never imports the simulator.

    python -m fleet.nodes.arm_controller --scene pick_cell --arm arm_0 --run demo --connect tcp/127.0.0.1:7447
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import threading
from collections import deque

import numpy as np
import zenoh

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.goals import goal_message
from fleet.bus.keys import Keys
from fleet.bus.messages import (
    ArmOrder,
    ArmState,
    ArmStatus,
    ControllerStep,
    PartsState,
    Roster,
)
from fleet.bus.session import BusEndpoints, Hold, Inbox, add_bus_arguments, open_session
from fleet.common.processes import add_scene_arguments, node_arguments, write_node_report
from fleet.common.realtime_priority import request_realtime_priority
from fleet.nodes.arm_orders import ControllerOrders
from fleet.nodes.sim_feed import SimFeed
from fleet.sight.line_sight import seen_ticks_of
from fleet.snapshot.controller_state import VERSION, ControllerState, read_controller_state
from fleet.snapshot.cut import controller_after_cut
from fleet.snapshot.process_state import StateError
from fleet.snapshot.snapshot_file import SnapshotError, node_state
from fleet.snapshot.snapshot_link import SnapshotLink
from robots.frames import yaw_transform
from robots.phase import Phase
from robots.registry import get_robot
from robots.saved_state import pack
from robots.skills.interface import ArmObservation, PickPlaceJob
from robots.skills.pick_place import DEFAULT_DECISION_HZ, PickPlaceSkill
from robots.skills.skill_state import restore_skill, skill_state
from scenes.schema import Arm, Scene

HEARTBEAT_S = 0.2  # wall seconds between heartbeats, on their own timer whatever the state traffic


def arm_declaration(scene: Scene, arm: str, rate_hz: float) -> Arm:
    """The scene's declaration of `arm`, once the arm and the rate are known to work (else one line, exit)."""
    decl = next((a for a in scene.arms if a.name == arm), None)
    if decl is None:
        raise SystemExit(
            f"arm_controller: no arm {arm!r} in scene {scene.name}; arms: {', '.join(a.name for a in scene.arms)}"
        )
    if not (math.isfinite(rate_hz) and 0 < rate_hz <= scene.control_hz):
        raise SystemExit(
            f"arm_controller: --rate-hz {rate_hz:g} must be within (0, {scene.control_hz:g}] (the scene's servo rate)"
        )
    return decl


def observation_of(state: ArmState) -> ArmObservation:
    """What the skill sees of its arm in a state."""
    return ArmObservation(
        state.sim_time_s,
        np.array(state.q),
        np.array(state.dq),
        np.array(state.gripper_q),
        state.result_goal_id,
        state.result_status,
        state.result_reason,
        goal_id=state.goal_id,
        held=state.held,
    )


class ArmController:
    """One arm's bridge (the skill state machine) on the bus: states in, trajectory goals and answers out."""

    def __init__(
        self,
        session: zenoh.Session,
        keys: Keys,
        arm: str,
        scene: Scene,
        *,
        grants: bool = False,
        rate_hz: float = DEFAULT_DECISION_HZ,
        incarnation: int | None = None,
        roster: bool = False,
        perception: str = "truth",
    ) -> None:
        decl = arm_declaration(scene, arm, rate_hz)
        self.seen = seen_ticks_of(scene) if perception == "cameras" else None  # the parts: perception's
        self.arm, self.keys, self.session = arm, keys, session
        self.arm_index = [a.name for a in scene.arms].index(arm)  # its place in the coordinator's order counts
        self.spec = get_robot(decl.model)
        self.period_ticks, self.hz = max(1, round(scene.control_hz / rate_hz)), scene.control_hz
        self.skill = PickPlaceSkill(
            self.spec,
            yaw_transform(decl.base.xyz, decl.base.yaw_rad),
            grants_required=grants,
            decision_period_s=self.period_ticks / scene.control_hz,
        )
        # differs each time a controller starts: the launcher counts its starts (so a seed repeats exactly), else random
        self.incarnation = incarnation if incarnation is not None else int.from_bytes(os.urandom(4), "little")
        self.skill.goal_id = (self.incarnation & 0x7FFFFFFF) << 20  # goal ids never repeat across a respawn
        self._wire(session, keys, scene)
        self.orders = ControllerOrders(arm, keys.arm_assign(arm), self._inboxes, self._decoders, self.drops, roster)
        self.feed = SimFeed(
            arm,
            self.spec.arm_dof,
            scene.control_hz,
            scene.round_part_types(),
            self._inboxes,
            self._decoders,
            self.drops,
            self.orders,
            self.seen,
        )
        self.delays = deque(maxlen=40)  # ticks each recent state spent on the bus on its way here
        self.task_id: int | None = None
        self.seq = 0
        self.sim_time_s = -1.0  # of the newest state answered (-1: none yet)
        self.answered: deque[int] = deque(maxlen=64)  # ticks answered lately (a future tick must not silence true ones)
        self.decisions = 0
        self.goals_sent = 0
        self.busy_s = 0.0

    def _wire(self, session: zenoh.Session, keys: Keys, scene: Scene) -> None:
        """Its decoders, queues, subscriptions (state, parts, orders) and publishers (answers, goals, heartbeats)."""
        self.drops = DropCounter()
        self._decoders = {
            "state": Decoder(ArmState, self.drops),
            "parts": Decoder(PartsState, self.drops),
            "assign": Decoder(ArmOrder, self.drops),
            "roster": Decoder(Roster, self.drops),
        }
        self.wake = threading.Event()
        self.hold = Hold(controller_after_cut)  # from a snapshot's tick until its part is sent
        self._inboxes = {name: Inbox(wake=self.wake, hold=self.hold) for name in ("state", "parts", "assign", "roster")}
        self._subs = [
            session.declare_subscriber(keys.arm_state(self.arm), self._inboxes["state"]),
            session.declare_subscriber(keys.parts if self.seen is None else keys.seen_parts, self._inboxes["parts"]),
            session.declare_subscriber(keys.arm_assign(self.arm), self._inboxes["assign"]),
            session.declare_subscriber(keys.roster, self._inboxes["roster"]),
        ]
        self._step_pub = session.declare_publisher(keys.arm_step(self.arm))
        self._goal_pub = session.declare_publisher(keys.arm_goal(self.arm))
        self._status_pub = session.declare_publisher(keys.arm_status(self.arm))
        self.snapshot_link = SnapshotLink(
            session, keys, self.arm, "controllers", self.drops, self.wake, lambda: self.incarnation, self.hold
        )

    def report(self) -> dict:
        """The controller's figures at the end of a run."""
        return {
            "arm": self.arm,
            "busy_s": round(self.busy_s, 6),
            "dropped_messages": self.drops.total,
            "refused_messages": self.drops.kinds(),
            "missed_assignments": self.orders.missed,
            "parts_late": self.feed.parts_late,
            "grants_denied": self.skill.grants.denials,
            "decisions": self.decisions,
            "goals_sent": self.goals_sent,
            "goals_resent": self.skill.goals_resent,
        }

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        for pub in (self._step_pub, self._goal_pub, self._status_pub):
            pub.undeclare()
        self.snapshot_link.close()

    def snapshot_part(self, ask) -> tuple[bytes, tuple]:
        """This controller's state, and the newest order it holds (the sim checks it against the coordinator's)."""
        return pack(controller_state(self)), (self.orders.assign_seq or 0,)

    def restore_state(self, data: bytes) -> None:
        """Put back a state from `snapshot_part` (also into the node that wrote it: it goes on from it)."""
        restore_controller(self, read_controller_state(data, self.arm))

    def snapshot_ready(self, ask) -> bool:
        """Whether every order the coordinator sent this arm and the newest parts message are in (the sim asks once
        it has every answer: nothing else is on its way)."""
        self.orders.take()
        self.feed.take_parts()
        sent = ask.orders[self.arm_index] if self.arm_index < len(ask.orders) else 0
        return (self.orders.assign_seq or 0) >= sent and self.feed.parts_in(ask.parts_tick)

    def poll(self) -> bool:
        """Handle what arrived; answer the newest state if there is one. True when an answer was sent."""
        if self.snapshot_link.serve(self.snapshot_ready, self.snapshot_part, self.restore_state):
            return True
        state = self.feed.latest_state()
        self.orders.take()
        if state is None or state.tick in self.answered:
            return False  # nothing new (the sim re-sends a state it is still waiting for: answered already)
        self.snapshot_link.expect(state.snapshot_tick)  # from that tick on, held until this node's part is sent
        self._catch_up(state)
        obs = observation_of(state)
        self._hand_to_skill(obs)
        if self.skill.active:
            self.busy_s += self.skill.plan.decision_period_s
        goals = self.skill.step(obs, self.feed.parts)
        if self.skill.job is None:  # clearing the way home: no task of the coordinator's
            self.task_id = None
        self._answer(state, goals)
        self.answered.append(state.tick)
        self.decisions += 1
        self.sim_time_s = state.sim_time_s
        return True

    def _catch_up(self, state: ArmState) -> None:
        """Before deciding on `state`: the orders it announces applied, the parts of its tick in, the latency known."""
        orders = self.orders
        if orders.assign_seq is None:  # a fresh (or respawned) controller owes nothing issued before it
            orders.assign_seq = max(0, state.assign_seq)
        elif state.assign_seq > orders.assign_seq:
            orders.await_order(state.assign_seq)
        orders.apply(state.assign_seq, self.skill)
        if self.skill.active or orders.pending is not None:  # only a task needs the parts: skip decoding otherwise
            if self.seen is None:
                self.feed.parts_for_tick(state.tick)
            else:  # perception's newest usable frame, carried to this state's tick
                self.feed.parts_for_tick(self.seen.usable_at(state.tick), state.tick)
        else:
            self.feed.skip_parts()
        self._expect_latency(state)

    def _hand_to_skill(self, obs: ArmObservation) -> None:
        """A pending assignment started (or refused: its part is gone), and the grants that came in answered."""
        if self.orders.pending is not None and self.skill.available:
            a, self.orders.pending = self.orders.pending, None
            task = PickPlaceJob(a.part_id, a.surface_z_m, tuple(a.place_xyz), tuple(a.surface_velocity))
            self.task_id = a.task_id
            part = self.feed.parts.get(a.part_id)
            if part is None:
                self.skill.reject(f"part {a.part_id} is not on the line")
            else:
                self.skill.start(task, obs, part)
        for g in self.orders.grants:
            self.skill.on_grant(
                g.request_seq, g.decision, g.conflict_arm, obs.time_s, g.start_time_s if g.start_time_s >= 0 else None
            )
        self.orders.grants.clear()

    def _answer(self, state: ArmState, goals: list) -> None:
        """The goals of this decision out, then the answer to `state` naming them (what the skill does, its request)."""
        for goal in goals:
            self._goal_pub.put(encode(goal_message(self.arm, goal)))
        self.goals_sent += len(goals)
        phase, progress = self.skill.phase.value, float(self.skill.progress)
        request = self.skill.request if self.skill.active else None
        self._step_pub.put(
            encode(
                ControllerStep(
                    self.arm,
                    state.tick,
                    state.tick + self.period_ticks,
                    tuple(g.goal_id for g in goals),
                    self.task_id,
                    phase,
                    progress,
                    self.skill.failure_reason if phase == Phase.FAILED else "",
                    self.skill.failure_code if phase == Phase.FAILED else "",
                    request.seq if request else 0,
                    request.q_to if request else (),
                    request.duration_s if request else 0.0,
                    tuple(v for q in request.then_q for v in q) if request else (),
                    request.then_after_s if request else (),
                )
            )
        )

    def _expect_latency(self, state: ArmState) -> None:
        """How long after a decision its goals reach the tracker: one period, plus the bus's delay both ways,
        measured on the states (the tick each arrived at, against the tick it was sampled) and taken as the
        same on the way back, at its recent worst."""
        delay = max(state.delivered_tick - state.tick, 0) if state.delivered_tick >= 0 else 0
        self.delays.append(delay)
        self.skill.plan.latency_s = self.skill.plan.decision_period_s + 2 * max(self.delays) / self.hz

    def send_heartbeat(self, sim_time_s: float) -> None:
        """The status the coordinator watches for liveness, with what the arm is doing: its phase, and the
        assignment it works on (or has taken and not started), which a respawned coordinator adopts."""
        self.seq += 1
        pending, task = self.orders.pending, self.skill.job  # read once: the heartbeat runs on its own thread
        task_id, part_id, place = self.task_id, -1, ()
        if pending is not None and pending.task_id is not None:
            task_id, part_id, place = pending.task_id, pending.part_id, tuple(pending.place_xyz)
        elif task is not None and task_id is not None:
            part_id, place = task.part_id, tuple(task.place_xyz)
        self._status_pub.put(
            encode(
                ArmStatus(
                    self.arm,
                    self.seq,
                    sim_time_s,
                    self.skill.phase.value,
                    task_id,
                    float(self.skill.progress),
                    self.busy_s,
                    self.skill.failure_reason,
                    self.incarnation,
                    part_id,
                    place,
                    -1 if self.orders.assign_seq is None else self.orders.assign_seq,
                )
            )
        )


def controller_state(c: ArmController) -> ControllerState:
    """What `c` saves in a run's snapshot."""
    return ControllerState(
        version=VERSION,
        incarnation=c.incarnation,
        skill=skill_state(c.skill),
        orders=c.orders.state(),
        feed=c.feed.state(),
        delays=list(c.delays),
        answered=list(c.answered),
        task_id=c.task_id,
        sim_time_s=c.sim_time_s,
        seq=c.seq,
        decisions=c.decisions,
        goals_sent=c.goals_sent,
        busy_s=c.busy_s,
        drops=c.drops.state(),
    )


def restore_controller(c: ArmController, s: ControllerState) -> None:
    """Put `s` back into `c`, a controller of the same arm (its bus handles and decoders stay; they count into
    the same drop counter)."""
    c.incarnation = s.incarnation
    restore_skill(c.skill, s.skill)
    c.orders.restore(s.orders)
    c.feed.restore(s.feed)
    c.delays.clear()
    c.delays.extend(s.delays)
    c.answered.clear()
    c.answered.extend(s.answered)
    c.task_id, c.sim_time_s, c.seq = s.task_id, s.sim_time_s, s.seq
    c.decisions, c.goals_sent, c.busy_s = s.decisions, s.goals_sent, s.busy_s
    c.drops.restore(s.drops)


def build_parser() -> argparse.ArgumentParser:
    """The arm controller's command line."""
    parser = argparse.ArgumentParser(prog="fleet-arm-controller", description=__doc__.splitlines()[0])
    add_scene_arguments(parser)
    parser.add_argument("--arm", required=True)
    parser.add_argument(
        "--grants", action="store_true", help="ask the coordinator for a motion grant before each free move"
    )
    parser.add_argument(
        "--rate-hz",
        type=float,
        default=DEFAULT_DECISION_HZ,
        help="decisions per sim second: the states this controller asks for (default 20)",
    )
    parser.add_argument(
        "--incarnation", type=int, default=None, help="this start's number (the launcher counts them; default random)"
    )
    parser.add_argument(
        "--roster",
        action="store_true",
        help="believe only the coordinator the launcher's roster names (`fleet run` sets it)",
    )
    parser.add_argument(
        "--rt", action="store_true", help="ask for real-time scheduling (SCHED_FIFO); falls back with a warning"
    )
    parser.add_argument("--report", help="write the end-of-run figures to this JSON file")
    parser.add_argument(
        "--from", dest="from_snapshot", metavar="SNAPSHOT", help="start from this arm's state in a run's snapshot"
    )
    add_bus_arguments(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    opened = node_arguments(build_parser(), argv, "arm_controller")
    if opened is None:
        return 2
    args, stop, scene = opened
    if args.rt:
        request_realtime_priority("arm_controller")
    with open_session(BusEndpoints.from_args(args)) as session:
        controller = ArmController(
            session,
            Keys(args.run),
            args.arm,
            scene,
            grants=args.grants,
            rate_hz=args.rate_hz,
            incarnation=args.incarnation,
            roster=args.roster,
            perception=args.perception,
        )
        if args.from_snapshot:
            try:
                snapshot, state = node_state(args.from_snapshot, args.arm)
                controller.restore_state(state)
            except (SnapshotError, StateError) as exc:
                print(f"arm_controller: {exc}", file=sys.stderr)
                controller.close()
                return 2
            controller.snapshot_link.back(snapshot.tick)
        beats = Heartbeat(controller)  # liveness on its own thread and clock, however long a decision takes
        try:
            while not stop.should_stop():
                if not controller.poll():
                    controller.wake.wait(0.05)
                    controller.wake.clear()
        finally:
            beats.stop()
            controller.close()
            write_node_report(args.report, controller.report() | {"stopped_by": stop.reason})
    return 0


class Heartbeat:
    """Sends the controller's status every `HEARTBEAT_S` from a thread of its own, from now until `stop`: the
    coordinator hears the process is alive while its loop waits for a state, a part or an order (up to
    `ASSIGNMENT_WAIT_S`) or plans; a process killed or frozen stops beating."""

    def __init__(self, controller: ArmController) -> None:
        self._stopped = threading.Event()
        self._controller = controller
        controller.send_heartbeat(controller.sim_time_s)
        self._thread = threading.Thread(target=self._run, name="heartbeat", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stopped.wait(HEARTBEAT_S):
            self._controller.send_heartbeat(self._controller.sim_time_s)

    def stop(self) -> None:
        self._stopped.set()
        self._thread.join(timeout=1.0)


if __name__ == "__main__":
    sys.exit(main())
