"""Which messages reaching a node were sent from a snapshot's tick boundary on (held back until the node's state as
of the boundary is written: `fleet.bus.session.Hold`), for the controller and the coordinator.

A node learns the boundary's tick ahead, from a state or frame (`snapshot_tick`), so it holds before anything of that
tick can be sent; the messages are told apart by the tick they carry: the tick a state or frame reached the node,
the tick of a parts message or a line event, of the decision that gave an order, the sim time of a heartbeat. (Each
subscriber's callback runs on a thread of its own, so arrival order alone cannot tell.) A message that cannot be
read passes: the node's loop drops and counts it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import msgspec

from fleet.bus.messages import ArmOrder, ArmState, ArmStatus, LineEvent, LineView, PartsState

_DECODERS = {
    "state": msgspec.msgpack.Decoder(ArmState),
    "parts": msgspec.msgpack.Decoder(PartsState),
    "assign": msgspec.msgpack.Decoder(ArmOrder),
    "events": msgspec.msgpack.Decoder(LineEvent),
    "frame": msgspec.msgpack.Decoder(LineView),
    "status": msgspec.msgpack.Decoder(ArmStatus),
}
_UNREADABLE = (msgspec.MsgspecError, UnicodeDecodeError, ValueError, OverflowError)


@dataclass(frozen=True)
class Cut:
    """A snapshot's tick boundary."""

    tick: int


def _arrived_tick(msg: ArmState | LineView) -> int:
    """The tick a state or frame reached its node (a delayed one is stamped with it)."""
    return msg.delivered_tick if msg.delivered_tick >= 0 else msg.tick


def controller_after_cut(key: str, payload: bytes, cut: Cut) -> bool:
    """For an arm's controller: states, parts and orders; rosters always pass."""
    leaf = key.rsplit("/", 1)[-1]
    if leaf not in ("state", "parts", "assign"):
        return False
    try:
        msg = _DECODERS[leaf].decode(payload)
    except _UNREADABLE:
        return False
    if leaf == "state":
        return _arrived_tick(msg) >= cut.tick
    if leaf == "parts":
        return msg.tick >= cut.tick
    return msg.decision_tick >= cut.tick


def coordinator_after_cut(control_hz: float) -> Callable[[str, bytes, Cut], bool]:
    """For the coordinator of a line ticking at `control_hz`; rosters always pass."""

    def after(key: str, payload: bytes, cut: Cut) -> bool:
        leaf = key.rsplit("/", 1)[-1]
        if leaf not in ("events", "frame", "status"):
            return False
        try:
            msg = _DECODERS[leaf].decode(payload)
        except _UNREADABLE:
            return False
        if leaf == "events":
            return msg.tick >= cut.tick
        if leaf == "frame":
            return _arrived_tick(msg) >= cut.tick
        return msg.sim_time_s >= (cut.tick - 0.5) / control_hz

    return after
