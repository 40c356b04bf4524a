"""A respawned coordinator taking over a running line: its ledger rebuilt from the sim's event log (`Keys.history`),
the task each controller's heartbeat says it works on adopted, its orders counted on from the controllers'."""

from __future__ import annotations

import sys
import time
from typing import Protocol

import zenoh

from coordinator.dispatcher import Dispatcher
from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.history import fetch_history
from fleet.bus.keys import Keys
from fleet.bus.message_checks import MAX_SEQ_JUMP, not_finite
from fleet.bus.messages import ArmStatus, LineView
from fleet.bus.session import Inbox
from fleet.nodes.controller_lives import ControllerLives
from fleet.nodes.coordinator_events import EventGate
from scenes.schema import Scene

TAKEOVER_WAIT_S = 2.0  # wall seconds a take-over waits for every arm's heartbeat (a dead controller's never comes)


class Coordinator(Protocol):
    """What a take-over rebuilds (`fleet.nodes.coordinator_node.CoordinatorNode`): its decisions, the events it
    holds, its view of the controllers and its order counts, from its queue and keys."""

    scene: Scene
    keys: Keys
    incarnation: int
    arm_names: list[str]
    inbox: Inbox
    drops: DropCounter
    replayed: set[tuple]
    events: EventGate
    dispatcher: Dispatcher
    lives: ControllerLives
    assign_seq: dict[str, int]

    def problem(self, leaf: str, msg, key: str = "") -> str: ...


def take_over(node: Coordinator, session: zenoh.Session, timeout_s: float = 30.0) -> dict:
    """Rebuild `node` from the running line (it replaces a coordinator that crashed): the sim's event log, then each
    arm's heartbeat (the task it works on, the orders it received). Returns what was rebuilt."""
    log = fetch_history(session, node.keys, node.drops, timeout_s)
    for e in log.events:
        node.replayed.add((e.kind, e.part_id, e.tick, e.detail))
        problem = node.problem("events", e)
        if problem:
            node.drops.drop(node.keys.history, problem)
        else:
            node.events.arrived(e, node.keys.history)
    node.events.apply(log.tick)
    node.events.seen = len(log.events)
    now_s = log.tick / node.scene.control_hz
    node.dispatcher.take_over(now_s)
    beats, announced = await_arms(node, TAKEOVER_WAIT_S)
    for arm, beat in beats.items():
        if announced.get(arm, 0) <= beat.assign_seq <= announced.get(arm, 0) + MAX_SEQ_JUMP:
            node.assign_seq[arm] = max(node.assign_seq[arm], beat.assign_seq)  # orders after those it has
        if beat.part_id >= 0 and beat.task_id is not None:
            node.dispatcher.adopt(arm, beat.task_id, beat.part_id, tuple(beat.place_xyz), now_s)
    takeover = {
        "incarnation": node.incarnation,
        "sim_time_s": round(now_s, 3),
        "events_replayed": len(log.events),
        "arms_heard": sorted(beats),
        "tasks_adopted": [a for a in node.dispatcher.takeover.adopted if a["adopted"]],
    }
    print(
        f"coordinator: took over the line at sim {takeover['sim_time_s']} s ({len(log.events)} events, "
        f"{len(takeover['tasks_adopted'])} task(s) adopted from {len(beats)} arm(s))",
        file=sys.stderr,
        flush=True,
    )
    return takeover


def await_arms(node: Coordinator, wait_s: float) -> tuple[dict[str, ArmStatus], dict[str, int]]:
    """Each arm's newest heartbeat and the order count the sim announced to it (a frame), waiting at most
    `wait_s` for all; what arrived meanwhile stays queued, in order, for `poll`."""
    beats: dict[str, ArmStatus] = {}
    announced: dict[str, int] = {}
    held: list[tuple[str, bytes]] = []
    peek = {"status": Decoder(ArmStatus, DropCounter()), "frame": Decoder(LineView, DropCounter())}  # `poll` counts
    deadline = time.monotonic() + wait_s
    while (len(beats) < len(node.arm_names) or not announced) and time.monotonic() < deadline:
        for key, payload in node.inbox.drain():
            held.append((key, payload))
            leaf = key.rsplit("/", 1)[-1]
            msg = peek[leaf].decode(key, payload) if leaf in peek else None
            if isinstance(msg, ArmStatus) and not node.lives.status_problem(key, msg) and not not_finite(msg.place_xyz):
                beats[msg.arm] = msg
            elif isinstance(msg, LineView) and not node.problem("frame", msg):
                announced = {s.arm: s.assign_seq for s in msg.arms}
        node.inbox.wait(0.02)
    node.inbox.items.extendleft(reversed(held))
    return beats, announced
