"""The coordinator process: the ledger and allocator of `coordinator/` behind the bus.

It listens to the sim's line events, to its frames (every arm's state, whose phase
echo says what each arm does in step with the sim clock, and the parts, in one
message every `1 / COORD_RATE_HZ` of sim time, `coordinator/cadence.py`) and to the controllers' heartbeats;
at each frame it refreshes the tasks, allocates them, answers motion requests and
publishes assignments. In lockstep it then answers the sim
with a `CoordTick`, so its decisions land on the same tick in every run. In realtime an arm
whose heartbeats stop for `heartbeat_timeout_s` (wall clock) is lost: its tasks
go back to the pool. In lockstep the sim's barrier judges instead (a controller that answers every
state is alive, however late a starved CPU runs its heartbeat thread): the wall clock decides nothing
in a run that repeats. It never imports the simulator.

A coordinator started with `--incarnation N` (N > 1: the launcher respawned it after a crash) takes
over the running line: it rebuilds its ledger from the sim's event log (`Keys.history`), adopts
the task each controller's heartbeat says it works on, counts its orders on from the controllers'
and gives no grant until every arm was seen holding still or idle (grants given before are unknown).

    python -m fleet.nodes.coordinator_node --scene assembly_line --run demo --connect tcp/127.0.0.1:7447
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
import zenoh

from coordinator.allocation import Allocator, make_allocator
from coordinator.allocator_plugins import AllocatorError, make_any_allocator
from coordinator.dispatch_state import dispatcher_state, restore_dispatcher
from coordinator.dispatcher import Dispatcher
from coordinator.guard import TimedPath
from coordinator.ledger import PIPELINE_DEFAULT
from coordinator.orders import Decision
from coordinator.reach_cache import save_shared
from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.history import HistoryUnavailable
from fleet.bus.keys import Keys
from fleet.bus.message_checks import TickClock, arm_state_problem, parts_problem
from fleet.bus.messages import (
    ArmState,
    ArmStatus,
    CoordTick,
    LineEvent,
    LineView,
    PartsState,
    Roster,
    separations_from_pairs,
)
from fleet.bus.session import BusEndpoints, Hold, Inbox, add_bus_arguments, open_session
from fleet.common.processes import add_scene_arguments, node_arguments, write_node_report
from fleet.nodes.allocator_eyes import AllocatorEyes
from fleet.nodes.controller_lives import ControllerLives, tell_lost
from fleet.nodes.coordinator_events import DecisionTimes, EventGate
from fleet.nodes.coordinator_orders import order_message, progress_message
from fleet.nodes.coordinator_takeover import take_over
from fleet.nodes.seen_parts import SeenParts
from fleet.sight.line_sight import seen_ticks_of
from fleet.sight.part_views import part_views
from fleet.snapshot.coordinator_state import VERSION, CoordinatorState, read_coordinator_state
from fleet.snapshot.cut import coordinator_after_cut
from fleet.snapshot.process_state import StateError
from fleet.snapshot.snapshot_file import SnapshotError, node_state
from fleet.snapshot.snapshot_link import SnapshotLink
from robots.registry import get_robot
from robots.saved_state import pack
from scenes.schema import Scene

PROGRESS_PERIOD_S = 0.5
TASK_ID_SPAN = 1 << 20  # task ids of each incarnation: a respawned coordinator never reuses one its predecessor gave
DECISION_WAIT_S = 0.5  # a reach check must not miss a reachable spot for an unlucky start
SIGHT_WAIT_S = 2.0  # lockstep: how long a decision waits for what it sees; under the sim's 3 s wait for us


class CoordinatorNode:
    """Decode, dispatch, publish: feed it with `poll()` in a loop; `report()` gives the coordinator's part of the
    run summary. Every decision is the `Dispatcher`'s; this node owns the bus, the wall clock (heartbeats,
    how long to wait for a decision's events) and the order counts of the protocol."""

    def __init__(
        self,
        session: zenoh.Session,
        keys: Keys,
        scene: Scene,
        *,
        lockstep: bool = True,
        allocator: Allocator | None = None,
        heartbeat_timeout_s: float = 0.75,
        incarnation: int = 1,
        pipeline: bool = PIPELINE_DEFAULT,
        roster: bool = False,
        perception: str = "truth",
    ) -> None:
        self.scene, self.keys, self.lockstep = scene, keys, lockstep
        self.incarnation = incarnation
        first_task_id = (incarnation - 1) * TASK_ID_SPAN + 1
        self.dispatcher = Dispatcher(scene, allocator or make_allocator("optimal", scene), first_task_id, pipeline)
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self.arm_names = [a.name for a in scene.arms]
        self.period_ticks = self.dispatcher.period_ticks
        self.drops = DropCounter()
        self.seen, self.eyes = self._senses(perception)
        self.events = EventGate(self.dispatcher, self.drops, scene.control_hz)
        self.decision_times = DecisionTimes()
        self._decoders = {
            "events": Decoder(LineEvent, self.drops),
            "frame": Decoder(LineView, self.drops),
            "status": Decoder(ArmStatus, self.drops),
            "roster": Decoder(Roster, self.drops),
            "parts": Decoder(PartsState, self.drops),
        }
        self.sim_clock = TickClock(scene.control_hz)  # frames and events are the sim's: none may run far ahead of it
        self._dof = {a.name: get_robot(a.model).arm_dof for a in scene.arms}
        self.hold = Hold(coordinator_after_cut(scene.control_hz))  # from a snapshot's tick until its part is sent
        # one queue for everything, in the order the callbacks ran: per key the order sent, across keys not (each
        # subscriber's callback has a thread of its own; a frame names the events before it, `EventGate` waits)
        self.inbox = Inbox(hold=self.hold)
        self.assign_seq = {a: 0 for a in self.arm_names}
        self.last_tick = {a: -1 for a in self.arm_names}
        self.lives = ControllerLives(
            self.arm_names, self.dispatcher, self.drops, self.assign_seq, roster, silence_loses=not lockstep
        )
        self._subs = self._subscribe(session, keys)
        self._declare_publishers(session, keys)
        self._progress_at = 0.0
        self.replayed: set[tuple] = set()  # events taken from the sim's log at a take-over (a live copy is not new)
        self.takeover: dict | None = None
        self.snapshot_link = SnapshotLink(
            session,
            keys,
            "coordinator",
            "coordinator",
            self.drops,
            self.inbox.wake,
            lambda: self.incarnation,
            self.hold,
        )

    def _senses(self, perception: str) -> tuple[SeenParts | None, AllocatorEyes | None]:
        """What this coordinator sees: with `cameras`, perception's parts (`seen/parts`) instead of the frames'
        (`docs/perception.md`); the cameras' frames, for an allocator that asks to see them (`frames_hz`)."""
        seen = SeenParts(seen_ticks_of(self.scene)) if perception == "cameras" else None
        frames_hz = getattr(self.dispatcher.allocator, "frames_hz", None)
        return seen, (AllocatorEyes(self.scene, frames_hz, self.drops) if frames_hz is not None else None)

    def _declare_publishers(self, session: zenoh.Session, keys: Keys) -> None:
        """Orders on each arm's `assign` key, the lockstep answer, progress, separations; and for an allocator that
        sees, `coord/eyes`, said until the first image comes (the sim starts then: its first frame is not lost)."""
        self._assign_pubs = {a: session.declare_publisher(keys.arm_assign(a)) for a in self.arm_names}
        self._tick_pub = session.declare_publisher(keys.coord("tick"))
        self._progress_pub = session.declare_publisher(keys.coord("progress"))
        self._separation_pub = session.declare_publisher(keys.coord("separation"))
        self._eyes_pub = session.declare_publisher(keys.coord("eyes")) if self.eyes is not None else None

    def _subscribe(self, session: zenoh.Session, keys: Keys) -> list:
        """Everything into the one inbox (perception's parts too, when the line works from its cameras); heartbeats
        and frames also stamped on arrival."""
        inbox_keys: tuple[str, ...] = ()  # what the line sees first: subscribed before the frames it comes with
        if self.eyes is not None:
            inbox_keys += tuple(keys.camera(c.name, kind) for c in self.eyes.cameras for kind in ("rgb", "depth"))
        inbox_keys += (keys.seen_parts,) if self.seen is not None else ()
        inbox_keys += (keys.events, keys.frame, keys.all_arms("status"), keys.roster)
        stamps = ((keys.all_arms("status"), self.lives.arrived), (keys.frame, self.lives.frame_arrived))
        subs = [session.declare_subscriber(k, self.inbox) for k in inbox_keys]
        return subs + [session.declare_subscriber(k, stamp) for k, stamp in stamps]  # heartbeats, frames: arrivals

    @property
    def events_seen(self) -> int:
        return self.events.seen

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        for pub in [*self._assign_pubs.values(), self._tick_pub, self._progress_pub, self._separation_pub]:
            pub.undeclare()
        if self._eyes_pub is not None:
            self._eyes_pub.undeclare()
        self.snapshot_link.close()

    # --- snapshots ------------------------------------------------------------------
    def snapshot_part(self, ask) -> tuple[bytes, tuple]:
        """The coordinator's state (`CoordinatorState`) and the newest order it sent each arm (the controllers'
        parts wait for them)."""
        return pack(coordinator_state(self)), tuple(self.assign_seq[a] for a in self.arm_names)

    def restore_state(self, data: bytes) -> None:
        """Put back a state from `snapshot_part` (also into the node that wrote it: it goes on from it). Wall-clock
        stamps start afresh: a heartbeat heard before the snapshot is no silence now, and no controller is judged
        before it beats again (each restores in its own time: a restored Panda's first beat came 0.77 s after this
        coordinator's, under load, and cost its arm); the line's bound is worked out again if the scene has a field
        set otherwise."""
        restore_coordinator(self, read_coordinator_state(data))
        self.dispatcher.scene_changed()
        self._progress_at = time.monotonic()

    def wait(self, timeout_s: float) -> None:
        """Sleep until a message arrives (heartbeat checks still run every `timeout_s`)."""
        self.inbox.wait(timeout_s)

    def take_over(self, session: zenoh.Session, timeout_s: float = 30.0) -> dict:
        """Rebuild from the running line (`fleet.nodes.coordinator_takeover`)."""
        self.takeover = take_over(self, session, timeout_s)
        return self.takeover

    # --- inputs ---------------------------------------------------------------------
    def poll(self) -> bool:
        """Handle everything queued, in order. True if anything was."""
        if self._eyes_pub is not None and not self.eyes.pairs.heard:
            self._eyes_pub.put(b"")
        items = self.inbox.drain()
        for key, payload in items:
            if self.eyes is not None and "/camera/" in key:
                self.eyes.take(key, payload)
                continue
            leaf = key.rsplit("/", 1)[-1]
            msg = self._decoders[leaf].decode(key, payload) if leaf in self._decoders else None
            if msg is None or (leaf == "events" and (msg.kind, msg.part_id, msg.tick, msg.detail) in self.replayed):
                continue
            problem = self.problem(leaf, msg, key)
            if problem:
                self.drops.drop(key, problem)
            elif leaf == "events":
                self.events.arrived(msg, key)
            elif leaf == "frame":
                self._on_frame(msg)
            elif leaf == "roster":
                self.lives.on_roster(key, msg)
            elif leaf == "parts":
                self.seen.take(msg)
            else:
                self.lives.on_status(key, msg)
        self.lives.check(self.heartbeat_timeout_s)
        self._decide_when_complete()
        self.snapshot_link.serve(lambda ask: self.events.seen >= ask.events, self.snapshot_part, self.restore_state)
        if time.monotonic() - self._progress_at > PROGRESS_PERIOD_S:
            self.publish_progress()
        return bool(items)

    def problem(self, leaf: str, msg, key: str = "") -> str:
        """Why a decoded message cannot be true ("" if it can): it is then dropped and counted, never acted on."""
        if leaf == "events":  # whether the line allows it is asked when it is applied (`EventGate.apply`)
            return self.sim_clock.problem(msg.tick)
        if leaf == "frame":
            problem = frame_problem(msg, self.sim_clock, self.arm_names, self._dof)
            if not problem:
                self.sim_clock.believe(msg.tick)
            return problem
        if leaf == "roster":
            return ""  # checked against the roster believed when it is heard (`_on_roster`)
        if leaf == "parts":
            return self.sim_clock.problem(msg.tick) or self.seen.problem(msg)
        return self.lives.status_problem(key, msg)

    def _on_frame(self, f: LineView) -> None:
        self.lives.frame_read()
        self.snapshot_link.expect(f.snapshot_tick)  # from that tick on, held until this node's part is sent
        for s in f.arms:
            self._on_state(s)
        self._on_parts(f.parts)

    def _on_state(self, s: ArmState) -> None:
        if s.arm not in self.last_tick or s.tick <= self.last_tick[s.arm]:
            return  # count each tick once
        self.last_tick[s.arm] = s.tick
        self.assign_seq[s.arm] = max(self.assign_seq[s.arm], s.assign_seq)  # after a take-over: count on from the sim's
        if s.taken:
            self.dispatcher.arm_taken(s.arm)
        else:
            self.dispatcher.arm_let_go(s.arm)
        lost = self.lives.on_sim_state(s.arm, s.lost)
        returned = self.dispatcher.on_arm(
            s.arm,
            np.asarray(s.q),
            s.phase,
            s.sim_time_s,
            task_id=s.task_id,
            failure=s.failure,
            failure_code=s.failure_code,
            request_seq=s.request_seq,
            request=motion_request(s),
            acts_at_tick=s.next_tick + s.period_ticks,  # heard with its next state, answered a period later
            lost=lost,
            silent_for_s=self.lives.silent_for_s(s.arm),
            gripper_q=np.asarray(s.gripper_q),
        )
        if returned is not None:
            tell_lost(s.arm, "the sim stopped hearing its controller", returned)

    def _on_parts(self, p: PartsState) -> None:
        if self.seen is None:  # else the frame's parts are empty: perception's come at each decision
            self.dispatcher.on_parts(part_views(p), p.sim_time_s)
        last = self.dispatcher.clock.last_decision_tick
        due = p.tick % self.period_ticks == 0 if self.lockstep else p.tick - last >= self.period_ticks
        if due and p.tick > last:  # a re-sent frame: once
            self.events.frame(p.tick, p.events_published, time.monotonic() + DECISION_WAIT_S)

    def _decide_when_complete(self) -> None:
        """Decide for the due frame's tick once every event published before it is in (`EventGate`), and with
        perception, the parts of the newest frame usable then (`SeenParts`); an allocator that sees is handed the
        cameras' frames of its look first (`AllocatorEyes`)."""
        now = time.monotonic()
        due = self.events.due
        if due is None:
            return
        shown = self.eyes.look_due(due[0]) if self.eyes is not None else None
        seen_waits = self.seen is not None and not self.seen.ready(due[0])
        longer_s = SIGHT_WAIT_S - DECISION_WAIT_S if self.lockstep else 0.0  # a lockstep sim waits for us anyway
        if (seen_waits or (shown is not None and not self.eyes.ready(shown))) and now <= due[2] + longer_s:
            return  # the frame's parts or the allocator's frames are still on their way
        tick = self.events.due_now(now)
        if tick is None:
            return
        if self.seen is not None:
            self.dispatcher.on_parts(*self.seen.views(tick))
        if shown is not None:  # an allocator that sees: the frames of its look, before it decides
            self.eyes.hand(self.dispatcher.allocator.see, shown)
        started = time.perf_counter()
        decision = self.dispatcher.decide(tick)
        self.decision_times.took(1e3 * (time.perf_counter() - started), tick)
        self.publish(decision)

    # --- outputs --------------------------------------------------------------------
    def publish(self, decision: Decision) -> None:
        """A decision's orders on each arm's `assign` key (one `seq` count per arm), then the lockstep barrier's
        answer."""
        if len(self.arm_names) > 1:
            now_s = decision.tick / self.scene.control_hz
            self._separation_pub.put(
                encode(separations_from_pairs(now_s, decision.separations, self.dispatcher.guard.margin_m))
            )
        for order in decision.orders:
            self.assign_seq[order.arm] += 1
            message = order_message(order, self.assign_seq[order.arm], self.incarnation, decision.tick)
            self._assign_pubs[order.arm].put(encode(message))
        self._tick_pub.put(encode(CoordTick(decision.tick, tuple(self.assign_seq[a] for a in self.arm_names))))

    def publish_progress(self) -> None:
        self._progress_at = time.monotonic()
        self._progress_pub.put(encode(progress_message(self.dispatcher)))

    def report(self) -> dict:
        self.events.apply(2**62)  # the run is over: every event counts
        return (
            self.dispatcher.report()
            | {
                "dropped_messages": self.drops.total,
                "refused_messages": self.drops.kinds(),
                "takeover": self.takeover,
                "decisions_on_deadline": self.events.decided_on_deadline,
                "decision_wall_ms": self.decision_times.summary() | self._reach_work(),
            }
            | ({"seen_parts": self._seen_report()} if self.seen is not None else {})
            | ({"allocator_eyes": self.eyes.report()} if self.eyes is not None else {})
        )

    def _seen_report(self) -> dict:
        frame_s = 1.0 / max(self.seen.ticks.rates_hz)
        return self.seen.report(self.scene.control_hz, frame_s)

    def _reach_work(self) -> dict:
        """The wall time spent working out reach cells the tables lacked, and how many (start-up included)."""
        reaches = {id(r): r for r in self.dispatcher.reach.values()}.values()
        return {
            "reach_ms": round(sum(r.search_s for r in reaches) * 1e3, 1),
            "reach_cells": sum(len(getattr(r, "worked_out", ())) for r in reaches),
        }


def frame_problem(f: LineView, clock: TickClock, arm_names: list[str], dof: dict[str, int]) -> str:
    """Why a frame cannot be the sim's ("" if it can): ahead of its clock, bad parts, another line's arms, a state
    that cannot be true, ticks mixed."""
    problem = clock.problem(f.tick) or parts_problem(f.parts)
    if not problem and sorted(s.arm for s in f.arms) != sorted(arm_names):
        problem = "a frame whose arms are not this line's"
    for s in f.arms if not problem else ():
        problem = (
            problem or arm_state_problem(s, s.arm, dof[s.arm]) or ("" if s.tick == f.tick else "a frame mixing ticks")
        )
    return problem


def motion_request(s: ArmState) -> TimedPath | None:
    """The move an arm holds still for, from its state (None when it asks for none)."""
    if not (s.request_seq > 0 and len(s.request_q_to) == len(s.q)):
        return None
    n = len(s.q)
    then_q = tuple(tuple(s.request_then_q[k : k + n]) for k in range(0, len(s.request_then_q), n))
    return TimedPath(
        s.arm,
        s.q,
        s.request_q_to,
        s.sim_time_s,
        s.sim_time_s + s.request_duration_s,
        then_q,
        tuple(s.request_then_after_s),
    )


def coordinator_state(node: CoordinatorNode) -> CoordinatorState:
    """What `node` saves in a run's snapshot."""
    return CoordinatorState(
        version=VERSION,
        incarnation=node.incarnation,
        dispatcher=dispatcher_state(node.dispatcher),
        events=node.events.state(),
        lives=node.lives.state(),
        decision_ms=list(node.decision_times.ms),
        slowest_decision=node.decision_times.slowest,
        sim_clock_newest=node.sim_clock.newest,
        assign_seq=dict(node.assign_seq),
        last_tick=dict(node.last_tick),
        replayed=set(node.replayed),
        takeover=node.takeover,
        drops=node.drops.state(),
    )


def restore_coordinator(node: CoordinatorNode, s: CoordinatorState) -> None:
    """Put `s` back into `node`, a coordinator of the same scene (its bus handles, decoders and allocator stay; the
    order counts are updated in place: its controller lives count on them)."""
    node.incarnation = s.incarnation
    restore_dispatcher(node.dispatcher, s.dispatcher)
    node.events.restore(s.events)
    node.lives.restore(s.lives)
    node.decision_times = DecisionTimes(list(s.decision_ms), s.slowest_decision)
    node.sim_clock.newest = s.sim_clock_newest
    node.assign_seq.clear()
    node.assign_seq.update(s.assign_seq)
    node.last_tick = dict(s.last_tick)
    node.replayed, node.takeover = set(s.replayed), s.takeover
    node.drops.restore(s.drops)


def build_parser() -> argparse.ArgumentParser:
    """The coordinator's flags (the scene's, its mode and allocator, the bus's)."""
    parser = argparse.ArgumentParser(prog="fleet-coordinator", description=__doc__.splitlines()[0])
    add_scene_arguments(parser)
    parser.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep")
    parser.add_argument(
        "--allocator",
        default="optimal",
        help="a built-in (optimal, auction, greedy), an installed plug-in's name, or package.module:Name",
    )
    parser.add_argument(
        "--no-pipeline",
        dest="pipeline",
        action="store_false",
        help="give a fixture's next part out only once the fixture is ready for it",
    )
    parser.add_argument("--report", help="write the end-of-run figures to this JSON file")
    parser.add_argument(
        "--incarnation",
        type=int,
        default=1,
        help="this run's Nth coordinator: from the 2nd on it takes over "
        "the running line (ledger rebuilt from the sim's event log and the controllers' heartbeats)",
    )
    parser.add_argument(
        "--roster",
        action="store_true",
        help="believe only the controllers' starts the launcher's roster names (`fleet run` sets it)",
    )
    parser.add_argument(
        "--from",
        dest="from_snapshot",
        metavar="SNAPSHOT",
        help="start from the coordinator's state in a run's snapshot (another --allocator than the snapshot's "
        "allocates from there on)",
    )
    add_bus_arguments(parser)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    opened = node_arguments(parser, argv, "coordinator")
    if opened is None:
        return 2
    args, stop, scene = opened
    if not 1 <= args.incarnation <= 1000:
        print(f"coordinator: --incarnation {args.incarnation} must be within 1..1000", file=sys.stderr)
        return 2
    try:
        allocator = make_any_allocator(args.allocator, scene)
    except AllocatorError as exc:  # unknown, or a plug-in that cannot be loaded or made
        print(f"coordinator: {exc}", file=sys.stderr)
        return 2
    with open_session(BusEndpoints.from_args(args)) as session:
        node = CoordinatorNode(
            session,
            Keys(args.run),
            scene,
            lockstep=args.mode == "lockstep",
            allocator=allocator,
            incarnation=args.incarnation,
            pipeline=args.pipeline,
            roster=args.roster,
            perception=args.perception,
        )
        _ = node.dispatcher.capacity  # worked out before the line starts: at the end it must not hold up the report
        try:
            if args.from_snapshot:
                try:
                    snapshot, state = node_state(args.from_snapshot, "coordinator")
                    node.restore_state(state)
                    if args.allocator != snapshot.allocator:  # a branch: another allocator from here on
                        node.dispatcher.allocator = allocator
                except (SnapshotError, StateError) as exc:
                    print(f"coordinator: {exc}", file=sys.stderr, flush=True)
                    return 2
                node.snapshot_link.back(snapshot.tick)
            elif args.incarnation > 1:
                try:
                    node.take_over(session)
                except HistoryUnavailable as exc:
                    print(f"coordinator: cannot take over the line: {exc}", file=sys.stderr, flush=True)
                    return 1
            while not stop.should_stop():
                if not node.poll():
                    node.wait(0.05)
        finally:
            node.publish_progress()
            node.close()
            write_node_report(args.report, node.report() | {"stopped_by": stop.reason})
            save_shared()  # the reach this run worked out, for the next (a forked node runs no exit handlers)
    return 0


if __name__ == "__main__":
    sys.exit(main())
