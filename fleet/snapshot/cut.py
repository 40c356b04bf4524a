"""Which messages reaching a node were sent from a snapshot's tick boundary on (held back until the node's state as
of the boundary is written: `fleet.bus.session.Hold`), for the controller and the coordinator.

A node learns the boundary's tick ahead, from a state or frame (`snapshot_tick`), so it holds before anything of that
tick can be sent; the messages are told apart by the tick they carry: the tick a state or frame reached the node,
the tick of a parts message or a line event, of the decision that gave an order, the sim time of a heartbeat. (Each
subscriber's callback runs on a thread of its own, so arrival order alone cannot tell.) A message that cannot be
read passes: the node's loop drops and counts it.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import msgspec

from fleet.bus.messages import ArmOrder, ArmState, ArmStatus, LineEvent, LineView, PartsState

_UNREADABLE = (msgspec.MsgspecError, UnicodeDecodeError, ValueError, OverflowError)


@dataclass(frozen=True)
class Cut:
    """A snapshot's tick boundary."""

    tick: int


def _arrived_tick(msg: ArmState | LineView) -> int:
    """The tick a state or frame reached its node (a delayed one is stamped with it)."""
    return msg.delivered_tick if msg.delivered_tick >= 0 else msg.tick


# by key leaf: the message type, and the tick it was sent at (a heartbeat's from its sim time, given the tick rate)
_SENT_AT = {
    "state": (msgspec.msgpack.Decoder(ArmState), lambda m, hz: _arrived_tick(m)),
    "frame": (msgspec.msgpack.Decoder(LineView), lambda m, hz: _arrived_tick(m)),
    "parts": (msgspec.msgpack.Decoder(PartsState), lambda m, hz: m.tick),
    "events": (msgspec.msgpack.Decoder(LineEvent), lambda m, hz: m.tick),
    "assign": (msgspec.msgpack.Decoder(ArmOrder), lambda m, hz: m.decision_tick),
    "status": (msgspec.msgpack.Decoder(ArmStatus), lambda m, hz: round(m.sim_time_s * hz)),
}


def _after(leaves: tuple[str, ...], key: str, payload: bytes, cut: Cut, hz: float) -> bool:
    leaf = key.rsplit("/", 1)[-1]
    if leaf not in leaves:
        return False
    decoder, sent_at = _SENT_AT[leaf]
    try:
        return sent_at(decoder.decode(payload), hz) >= cut.tick
    except _UNREADABLE:
        return False


def controller_after_cut(key: str, payload: bytes, cut: Cut) -> bool:
    """For an arm's controller: states, parts and orders; rosters always pass."""
    return _after(("state", "parts", "assign"), key, payload, cut, 0.0)


def coordinator_after_cut(control_hz: float) -> Callable[[str, bytes, Cut], bool]:
    """For the coordinator of a line ticking at `control_hz`: frames, line events and heartbeats; rosters pass."""
    return functools.partial(_after, ("frame", "events", "status"), hz=control_hz)
