"""The sim asking the nodes for their states at a snapshot's tick boundary (one concern of `SimSnapshots`, kept
apart), and a restored sim asking them whether they are back.

The cut: the sim first waits until every state and frame it delivered is answered (lockstep makes that a
consistent cut: nothing else is on its way). In lockstep it then asks the coordinator and every controller at
once: each controller waits for the orders the coordinator's answers to the frames announced (`CoordTick`), and
one found to have fewer than the coordinator says it sent (an order outside a decision) is asked again with the
coordinator's count. In realtime (the coordinator answers no frame) the coordinator is asked first.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from fleet.bus.codec import Decoder, encode
from fleet.bus.lockstep import unanswered
from fleet.bus.messages import SnapshotAsk, SnapshotPart

NODE_TIMEOUT_S = 10.0  # wall seconds a node has to send its part of a snapshot
RESTORED_TIMEOUT_S = 60.0  # wall seconds every node of a restored run has to say it is back
ASK_AGAIN_S = 0.5


class SnapshotFailed(RuntimeError):
    """A snapshot that could not be taken (a node silent or unable to write its state); one line."""


def node_states(sim, stage: Callable[[str], None]) -> dict[str, SnapshotPart]:
    """Every node's part of a snapshot at this tick (`stage(name)` marks where the time goes)."""
    settle(sim)
    stage("settle")
    tick = sim.world.tick
    arms = [name for name, link in sim.links.items() if not link.lost]
    lost = sorted(set(sim.links) - set(arms))
    if lost:
        raise SnapshotFailed(f"the controllers of {', '.join(lost)} are lost")
    coord_ask = SnapshotAsk(tick, "coordinator", events=len(sim.event_log))
    if sim.mode == "lockstep":
        parts = ask(sim, [coord_ask, controllers_ask(sim, orders_announced(sim))], ["coordinator", *arms])
        behind = [a for i, a in enumerate(sim.links) if parts[a].orders[:1] < parts["coordinator"].orders[i : i + 1]]
        if behind:
            parts |= ask(sim, [controllers_ask(sim, parts["coordinator"].orders)], behind)
        stage("nodes")
    else:
        parts = ask(sim, [coord_ask], ["coordinator"])
        stage("coordinator")
        parts |= ask(sim, [controllers_ask(sim, parts["coordinator"].orders)], arms)
        stage("controllers")
    return parts


def orders_announced(sim) -> tuple[int, ...]:
    """Each arm's newest order the coordinator has said it sent (its answers to the frames, applied or not)."""
    newest = dict(sim.assign_seqs)
    for flight in sim.coord_book.flights.values():
        if flight.answer is not None:
            for name, seq in zip(sim.links, flight.answer.assign_seqs):
                newest[name] = max(newest[name], seq)
    return tuple(newest[name] for name in sim.links)


def controllers_ask(sim, orders: tuple[int, ...]) -> SnapshotAsk:
    return SnapshotAsk(sim.world.tick, "controllers", orders=tuple(orders), parts_tick=sim.outputs.parts_tick)


def settle(sim) -> None:
    """Until every state and frame delivered is answered (with the goals the answers name)."""
    deadline = time.monotonic() + NODE_TIMEOUT_S
    coord_book = sim.coord_book if sim.coordinator and sim.mode == "lockstep" else None  # realtime: unanswered
    while True:
        sim.inputs.take()
        waiting, coord = unanswered(list(sim.links.values()), coord_book)
        if not waiting and not coord:
            return
        if time.monotonic() > deadline:
            names = [link.name for link in waiting] + (["coordinator"] if coord else [])
            raise SnapshotFailed(f"{', '.join(names)} did not answer within {NODE_TIMEOUT_S:g} s")
        sim.bus.inbox.wait(0.01)


def ask(sim, asks: list[SnapshotAsk], nodes: list[str]) -> dict[str, SnapshotPart]:
    """`asks` published until each of `nodes` sent its part for this tick; a part made for another ask of the same
    tick (fewer orders) is not taken."""
    controllers, arms, tick = next((a for a in asks if a.node == "controllers"), None), list(sim.links), asks[0].tick

    def take(part: SnapshotPart) -> bool:
        if part.restored or part.tick != tick:
            return False
        if part.error:
            raise SnapshotFailed(f"{part.node}: {part.error}")
        return part.node == "coordinator" or _answers(part, controllers, arms)

    got = collect(sim, asks, nodes, take, NODE_TIMEOUT_S)
    silent = [n for n in nodes if n not in got]
    if silent:
        raise SnapshotFailed(f"{', '.join(silent)} sent no state within {NODE_TIMEOUT_S:g} s")
    return got


def await_restored(sim, tick: int, nodes: list[str], timeout_s: float = RESTORED_TIMEOUT_S) -> list[str]:
    """A restored sim, before its first tick: ask until each of `nodes` said it is back at `tick`; those that did not
    within `timeout_s` or before the sim was stopped (empty: all did)."""
    back = collect(sim, [SnapshotAsk(tick, "restored")], nodes, lambda p: p.restored and p.tick == tick, timeout_s)
    return [n for n in nodes if n not in back]


def collect(
    sim, asks: list[SnapshotAsk], nodes: list[str], take: Callable[[SnapshotPart], bool], timeout_s: float
) -> dict[str, SnapshotPart]:
    """`asks` published (again every `ASK_AGAIN_S`), and the parts `take` accepts kept by node, until each of `nodes`
    sent one, `timeout_s` passed or the sim is stopped."""
    decoder = Decoder(SnapshotPart, sim.drops)
    got: dict[str, SnapshotPart] = {}
    deadline, asked = time.monotonic() + timeout_s, -float("inf")
    while len(got) < len(nodes) and time.monotonic() < deadline:
        if sim.stop is not None and sim.stop.should_stop():
            break
        if time.monotonic() - asked > ASK_AGAIN_S:
            for a in asks:
                sim.bus.snapshot_pub.put(encode(a))
            asked = time.monotonic()
        for key, payload in sim.bus.snapshot_inbox.drain():
            part = decoder.decode(key, payload)
            if part is not None and part.node in nodes and take(part):
                got[part.node] = part
        sim.bus.snapshot_inbox.wait(0.01)
    return got


def _answers(part: SnapshotPart, controllers: SnapshotAsk | None, arms: list[str]) -> bool:
    """Whether a controller's part holds the orders the ask named for it."""
    if controllers is None:
        return False
    i = arms.index(part.node)
    return bool(part.orders) and part.orders[0] >= (controllers.orders[i] if i < len(controllers.orders) else 0)
