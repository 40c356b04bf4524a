"""What the coordinator saves in a run's snapshot: its decisions' state (`coordinator.dispatch_state`), the events it
holds for a decision, what it believes of the controllers' lives and its order counts; not its bus handles, nor
what it was started with (scene, clock, heartbeat timeout, allocator), which the coordinator it is put back into
has."""

from __future__ import annotations

from typing import Any

from coordinator.dispatch_state import DispatcherState
from fleet.bus.message_checks import IncarnationsState
from fleet.bus.messages import LineEvent
from fleet.snapshot.process_state import StateError
from robots.saved_state import SavedState, SavedStateError, unpack_version

VERSION = 1  # bumped when a field keeps its name and type but changes its meaning


class EventGateState(SavedState, frozen=True):
    """What `fleet.nodes.coordinator_events.EventGate` saves."""

    seen: int
    ahead: list[tuple[str, LineEvent]]
    due: tuple[int, int, float] | None
    decided_on_deadline: int


class LivesState(SavedState, frozen=True):
    """What `fleet.nodes.controller_lives.ControllerLives` saves (its wall-clock stamps start afresh)."""

    incarnations: IncarnationsState
    controller_incarnation: dict[str, int]
    rejoining: set[str]
    sim_lost: set[str]
    replaced: dict[str, set[int]]


class CoordinatorState(SavedState, frozen=True):
    """The coordinator node's state (`fleet.nodes.coordinator_node.coordinator_state`, `restore_coordinator`)."""

    version: int
    incarnation: int
    dispatcher: DispatcherState
    events: EventGateState
    lives: LivesState
    decision_ms: list[float]  # wall milliseconds each decision took
    slowest_decision: tuple[float, int]  # (ms, tick)
    sim_clock_newest: int | None  # the newest tick believed from the sim
    assign_seq: dict[str, int]
    last_tick: dict[str, int]
    replayed: set[tuple[str, int, int, str]]  # events taken from the sim's log at a take-over
    takeover: dict[str, Any] | None  # the summary's `coordinator_takeover`
    drops: list[tuple[str, str, int]]  # messages dropped: key, reason, how many


def read_coordinator_state(data: bytes) -> CoordinatorState:
    """A coordinator's state from its bytes; another version, or bytes that are not one, is a one-line
    `StateError`."""
    try:
        return unpack_version(data, CoordinatorState, VERSION)
    except SavedStateError as exc:
        raise StateError(f"cannot read back the state of the coordinator: {exc}") from None
