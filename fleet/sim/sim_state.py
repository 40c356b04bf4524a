"""What the sim server saves in a run's snapshot: its world, each arm's link and tracker, the coordinator's flights,
the line's watch, events and counts, and what it says and hears on the bus; not its bus handles, nor what it was
started with (scene, clock, speed, timeouts, who it waits for), which the sim it is put back into has."""

from __future__ import annotations

from fleet.bus.faults import FaultyLinkState
from fleet.bus.flights import BookState
from fleet.bus.lockstep import ArmLinkState
from fleet.bus.messages import CoordTick, LineEvent, LineView
from fleet.sim.line_watch import WatcherState
from fleet.sim.sim_inputs import InputsState
from fleet.sim.sim_outputs import OutputsState
from fleet.sim.sim_stats import StatsState
from fleet.sim.tracking import TrackedState
from fleet.sim.world import WorldState
from fleet.snapshot.process_state import StateError
from robots.saved_state import SavedState, SavedStateError, unpack_version

VERSION = 1  # bumped when a field keeps its name and type but changes its meaning


class SimState(SavedState, frozen=True):
    """A `fleet.sim.server.SimServer`'s state (`fleet.sim.sim_snapshot.sim_state`, `restore_sim`)."""

    version: int
    world: WorldState
    links: dict[str, ArmLinkState]
    coordinator_book: BookState[LineView, CoordTick]
    faults: dict[str, FaultyLinkState]  # every link's, the coordinator's too
    tracked: TrackedState
    watcher: WatcherState
    stats: StatsState
    inputs: InputsState
    outputs: OutputsState
    event_log: list[LineEvent]
    assign_seqs: dict[str, int]
    estop: bool
    paused: bool
    started: bool
    drops: list[tuple[str, str, int]]  # messages dropped: key, reason, how many


def read_sim_state(data: bytes) -> SimState:
    """A sim's state from its bytes; another version, or bytes that are not one, is a one-line `StateError`."""
    try:
        return unpack_version(data, SimState, VERSION)
    except SavedStateError as exc:
        raise StateError(f"cannot read back the state of the sim: {exc}") from None
