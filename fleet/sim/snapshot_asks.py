"""The sim asking the nodes for their states at a snapshot's tick boundary (one concern of `SimSnapshots`, kept
apart), and a restored sim asking them whether they are back.

The cut: the sim first waits until every state and frame it delivered is answered (lockstep makes that a
consistent cut: nothing else is on its way). In lockstep it then asks the coordinator and every controller at
once and goes on (`fleet.sim.snapshot_parts` gathers the parts): each controller waits for the orders the
coordinator's answers to the frames announced (`CoordTick`), and each node holds back what reaches it behind the
ask. In realtime (the coordinator answers no frame) the coordinator is asked first, then the controllers with its
counts, the line paused until every part is in.
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


def lockstep_asks(sim, stage: Callable[[str], None]) -> tuple[list[SnapshotAsk], list[str], list[str]]:
    """At a lockstep tick boundary, with every answer in: the asks for every node's part (the coordinator's and the
    controllers', sent at once), the nodes that owe one (the coordinator, then the arms in the scene's order) and the
    arms whose controllers are lost (a snapshot fails then: it is asked for all the same)."""
    settle(sim)
    stage("settle")
    lost = lost_arms(sim)
    return asks_at_boundary(sim), ["coordinator", *(a for a in sim.links if a not in lost)], lost


def asks_at_boundary(sim) -> list[SnapshotAsk]:
    """The coordinator's ask and the controllers' (each controller waits for the orders the coordinator's answers
    to the frames announced)."""
    return [coordinator_ask(sim), controllers_ask(sim, orders_announced(sim))]


def node_states(sim, stage: Callable[[str], None]) -> dict[str, SnapshotPart]:
    """Realtime (the coordinator answers no frame, so its orders are known only from its part): every node's part
    of a snapshot at this tick, the coordinator asked first, then the controllers with its counts, the line paused
    meanwhile (`stage(name)` marks where the time goes)."""
    settle(sim)
    stage("settle")
    lost = lost_arms(sim)
    if lost:
        raise SnapshotFailed(f"the controllers of {', '.join(lost)} are lost")
    parts = ask(sim, [coordinator_ask(sim)], ["coordinator"])
    stage("coordinator")
    parts |= ask(sim, [controllers_ask(sim, parts["coordinator"].orders)], list(sim.links))
    stage("controllers")
    return parts


def lost_arms(sim) -> list[str]:
    """The arms whose controllers the line has lost (a snapshot fails while one is)."""
    return sorted(name for name, link in sim.links.items() if link.lost)


def publish_asks(sim, asks: list[SnapshotAsk]) -> None:
    for a in asks:
        sim.bus.snapshot_pub.put(encode(a))


def orders_announced(sim) -> tuple[int, ...]:
    """Each arm's newest order the coordinator has said it sent (its answers to the frames, applied or not)."""
    newest = dict(sim.assign_seqs)
    for flight in sim.coord_book.flights.values():
        if flight.answer is not None:
            for name, seq in zip(sim.links, flight.answer.assign_seqs):
                newest[name] = max(newest[name], seq)
    return tuple(newest[name] for name in sim.links)


def coordinator_ask(sim) -> SnapshotAsk:
    return SnapshotAsk(sim.world.tick, "coordinator", events=len(sim.event_log))


def controllers_ask(sim, orders: tuple[int, ...]) -> SnapshotAsk:
    return SnapshotAsk(sim.world.tick, "controllers", orders=tuple(orders), parts_tick=sim.outputs.parts_tick)


def settle(sim) -> None:
    """Until every state and frame delivered is answered (with the goals the answers name)."""
    deadline = time.monotonic() + NODE_TIMEOUT_S
    coord_book = sim.coord_book if sim.controls.coordinator and sim.controls.lockstep else None  # realtime: unanswered
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
    controllers = next((a for a in asks if a.node == "controllers"), None)
    arms, of_tick = list(sim.links), part_of(asks)

    def take(part: SnapshotPart) -> bool:
        return of_tick(part) and (part.node == "coordinator" or _answers(part, controllers, arms))

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
            publish_asks(sim, asks)
            asked = time.monotonic()
        take_parts(sim, decoder, nodes, take, got)
        sim.bus.snapshot_inbox.wait(0.01)
    return got


def take_parts(
    sim, decoder: Decoder, nodes: list[str], take: Callable[[SnapshotPart], bool], got: dict[str, SnapshotPart]
) -> None:
    """The parts arrived so far that `take` accepts, from `nodes`, into `got` by node."""
    for key, payload in sim.bus.snapshot_inbox.drain():
        part = decoder.decode(key, payload)
        if part is not None and part.node in nodes and take(part):
            got[part.node] = part


def part_of(asks: list[SnapshotAsk]) -> Callable[[SnapshotPart], bool]:
    """Whether a part answers these asks' tick (not a restored node's "back"); a node's answer that it has no state
    fails the snapshot (`SnapshotFailed`)."""
    tick = asks[0].tick

    def of_tick(part: SnapshotPart) -> bool:
        if part.restored or part.tick != tick:
            return False
        if part.error:
            raise SnapshotFailed(f"{part.node}: {part.error}")
        return True

    return of_tick


def _answers(part: SnapshotPart, controllers: SnapshotAsk | None, arms: list[str]) -> bool:
    """Whether a controller's part holds the orders the ask named for it."""
    if controllers is None:
        return False
    i = arms.index(part.node)
    return bool(part.orders) and part.orders[0] >= (controllers.orders[i] if i < len(controllers.orders) else 0)
