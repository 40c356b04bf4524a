"""The sim server's side of the bus: what it subscribes to (answers and goals in one queue, in arrival order; e-stop,
coordinator ticks and clock controls each in their own), what it serves (its scene, its event log), what it
publishes, every message counted by key leaf; and the checks its inputs pass before they are believed."""

from __future__ import annotations

import math
from collections.abc import Callable

import zenoh

from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.history import serve_history
from fleet.bus.keys import Keys
from fleet.bus.message_checks import seq_problem
from fleet.bus.messages import ArmGoalMsg, ControllerStep, CoordTick, EStop, EventLog, Roster, SimControl
from fleet.bus.scene_query import serve_scene
from fleet.bus.session import Inbox
from fleet.sim.sim_stats import SimStats


class SimBus:
    """Subscriptions, queryables and publishers of one sim server; `close` undeclares them all."""

    def __init__(
        self,
        session: zenoh.Session,
        keys: Keys,
        arms: list[str],
        scene_json: str,
        history: Callable[[], EventLog],
        stats: SimStats,
    ) -> None:
        self.session, self.stats = session, stats
        self.drops = DropCounter()
        self.control = Decoder(SimControl, self.drops)
        self.step = Decoder(ControllerStep, self.drops)
        self.goal = Decoder(ArmGoalMsg, self.drops)
        self.estop = Decoder(EStop, self.drops)
        self.coord = Decoder(CoordTick, self.drops)
        self.inbox = Inbox()  # answers and goals in one queue: handled in arrival order
        self.estop_inbox, self.coord_inbox = Inbox(wake=self.inbox.wake), Inbox(wake=self.inbox.wake)
        self.control_inbox = Inbox(wake=self.inbox.wake)
        self.snapshot_inbox = Inbox()  # the nodes' parts of a snapshot (`fleet/sim/sim_snapshot.py`)
        self.roster = Decoder(Roster, self.drops)
        self.roster_inbox = Inbox()  # the launcher's rosters: which start of each node runs (a snapshot's parts)
        self._subs = [
            session.declare_subscriber(keys.all_arms("step"), self.inbox),
            session.declare_subscriber(keys.all_arms("goal"), self.inbox),
            session.declare_subscriber(keys.all_arms("drive"), self.inbox),
            session.declare_subscriber(keys.estop, self.estop_inbox),
            session.declare_subscriber(keys.coord("tick"), self.coord_inbox),
            session.declare_subscriber(keys.control, self.control_inbox),
            session.declare_subscriber(keys.snapshot_parts(), self.snapshot_inbox),
            session.declare_subscriber(keys.roster, self.roster_inbox),
        ]
        self._queryables = [serve_scene(session, keys, scene_json), serve_history(session, keys, history)]
        self.status_pub = session.declare_publisher(keys.sim_status)
        self.view_pub = session.declare_publisher(keys.view)
        self.frame_pub = session.declare_publisher(keys.frame)
        self.state_pubs = {name: session.declare_publisher(keys.arm_state(name)) for name in arms}
        self.result_pubs = {name: session.declare_publisher(keys.arm_result(name)) for name in arms}
        self.parts_pub = session.declare_publisher(keys.parts)
        # never dropped for a full queue: every reader counts the line's events (perception waits for those a frame
        # names), and in lockstep a node told of a snapshot holds the line's messages until asked
        block = zenoh.CongestionControl.BLOCK
        self.events_pub = session.declare_publisher(keys.events, congestion_control=block)
        self.snapshot_pub = session.declare_publisher(keys.snapshot_ask, congestion_control=block)

    def put(self, pub: zenoh.Publisher, leaf: str, payload: bytes) -> None:
        pub.put(payload)
        self.stats.messages_out[leaf] += 1

    def watched(self) -> bool:
        """Whether a monitor listens to the view (it is built only then)."""
        return self.view_pub.matching_status.matching

    def close(self) -> None:
        for sub in self._subs:
            sub.undeclare()
        for queryable in self._queryables:
            queryable.undeclare()
        pubs = [
            *self.state_pubs.values(),
            *self.result_pubs.values(),
            self.parts_pub,
            self.events_pub,
            self.status_pub,
            self.view_pub,
            self.frame_pub,
            self.snapshot_pub,
        ]
        for pub in pubs:
            pub.undeclare()


def control_problem(msg: SimControl) -> str:
    """Why a clock control is not believed ("" when it is)."""
    if msg.speed is not None and not (math.isfinite(msg.speed) and 0.01 <= msg.speed <= 100.0):
        return "speed factor outside 0.01..100"
    return ""


def coord_tick_problem(msg: CoordTick, arms: list[str], assign_seqs: dict[str, int], tick: int) -> str:
    """Why a coordinator tick is not believed ("" when it is): another line's arms, a frame not sent yet, orders
    numbered out of turn."""
    if len(msg.assign_seqs) != len(arms):
        return f"coordinator tick with {len(msg.assign_seqs)} arms, the scene has {len(arms)}"
    if msg.tick > tick:
        return f"coordinator tick {msg.tick} answers a frame not sent yet (now {tick})"
    return next((p for n, q in zip(arms, msg.assign_seqs) if (p := seq_problem(q, assign_seqs[n]))), "")
