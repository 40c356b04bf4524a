"""The sim's side of a run's snapshots: at a tick boundary, with every answer in, every node's state
(`fleet.sim.snapshot_asks`) and its own, into one file; and a sim started from a snapshot, put back and holding the
line until every node says it is back too.

The cut is consistent because lockstep makes it so: the sim has every answer to what it delivered (in its flight
books), the coordinator has every line event published, and each controller every order the coordinator says it sent
and the newest parts message. Nothing else is on its way while the sim waits. Each process then goes on from the
state it wrote, read back (`fleet.snapshot.process_state`): the run that took the snapshot and a run restored from it
continue from byte-identical states (a world put back from PhysX's pack matches the one packed only to about 1e-6).
"""

from __future__ import annotations

import statistics
import threading
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path

from fleet.bus.messages import SnapshotPart
from fleet.sim.sim_state import VERSION, SimState, read_sim_state
from fleet.sim.snapshot_asks import SnapshotFailed, asks_at_boundary, lockstep_asks, node_states, publish_asks
from fleet.sim.snapshot_parts import BASELINE_WINDOWS, CostDue, NextTicks, NodeStarts, PartsDue, check_starts
from fleet.sim.world import World
from fleet.snapshot.process_state import StateError
from fleet.snapshot.snapshot_file import SUFFIX, RunSnapshot, SceneSource, write_snapshot
from robots.saved_state import SavedStateError, pack


@dataclass
class RunFacts:
    """What a snapshot file says about the run beside the states: its scene's source, allocator and end."""

    scene_name: str
    scene: SceneSource
    allocator: str
    end_tick: int


@dataclass
class SimSnapshots:
    """Snapshots due at `ticks` (and every `every_ticks` from the start, if set), written to `directory` (None: taken,
    not written; a restored run retakes its original's, so as to go on exactly as it did)."""

    sim: object
    facts: RunFacts
    directory: Path | None
    ticks: set[int] = field(default_factory=set)
    every_ticks: int = 0
    written: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    stall_s: list[float] = field(default_factory=list)  # how long the sim loop stood still for each
    next_ticks_s: list[float] = field(default_factory=list)  # how much longer the ticks after each took (`CostDue`)
    stages_ms: list[dict[str, float]] = field(default_factory=list)  # each snapshot's stall, by stage
    bytes_written: list[int] = field(default_factory=list)
    write_ms: list[float] = field(default_factory=list)  # compressing and writing each file (the line goes on)
    _stage_at: float = 0.0
    _writer: threading.Thread | None = None
    _builder: threading.Thread | None = None  # building the spare world
    _spare: list = field(default_factory=list)  # the world the line goes on in after the next snapshot
    _pending: tuple[PartsDue, tuple[int, float, bytes]] | None = None  # the parts still coming, the sim's facts
    _costs: list[CostDue] = field(default_factory=list)  # snapshots whose ticks after are still being measured
    _next_ticks: NextTicks = field(init=False)  # the wall time at the last tick boundaries
    last_tick: int = 0  # the tick of the last snapshot taken (or restored from): never twice at one tick
    starts: NodeStarts = field(default_factory=NodeStarts)  # the start of each node running (the launcher's roster)

    def __post_init__(self) -> None:
        # enough boundaries for the runs of ticks a cost is measured against: a few of the longest a node may wait
        longest = max(self.sim.cadence.coord_period_ticks, self.sim.cadence.max_period_ticks)
        self._next_ticks = NextTicks(longest * BASELINE_WINDOWS)

    def due(self, tick: int) -> bool:
        """Whether a snapshot is scheduled at this tick (never twice at one)."""
        every = self.every_ticks > 0 and tick % self.every_ticks == 0
        return tick != self.last_tick and tick > 0 and (tick in self.ticks or every)

    def next_due(self, tick: int) -> int:
        """The tick of the next snapshot scheduled after `tick` and before the run's end (-1: none; one at the end
        is never taken, and a node told of it would hold the line's last events)."""
        later = [t for t in self.ticks if t > tick]
        if self.every_ticks > 0:
            later.append((tick // self.every_ticks + 1) * self.every_ticks)
        return min((t for t in later if t < self.facts.end_tick), default=-1)

    def take(self) -> None:
        """The run's snapshot at this tick boundary. In lockstep the nodes' parts are gathered while the line goes
        on (`pump`), then the file written; in realtime the line waits for them. One that fails is counted and
        said; the line goes on either way."""
        t0 = self._stage_at = time.perf_counter()
        self.stages_ms.append({})
        sim = self.sim
        self._complete_pending()  # the last snapshot's parts all in before another is asked for
        self.last_tick = sim.world.tick
        try:
            if sim.controls.lockstep:
                own, due, parts = self._take_lockstep()
            else:
                alive = self.starts.now(self.sim.bus)
                due, parts = None, node_states(sim, self._stage)
                check_starts(parts, alive)
                own = self._own_state()
        except (SnapshotFailed, StateError) as exc:
            self.stages_ms.pop()  # by stage, as `stall_s`: the snapshots taken
            self._failed(sim.world.tick, exc)
            return
        self.stall_s.append(time.perf_counter() - t0)
        facts = (sim.world.tick, sim.world.sim_time_s, own)
        if due is None:
            self._write_file(facts, parts)
            return
        self._pending = (due, facts)
        span = max([sim.cadence.coord_period_ticks, *(link.period_ticks for link in sim.links.values())])
        self._costs.append(CostDue(sim.world.tick, span, self._next_ticks.before_s(span)))

    def _take_lockstep(self) -> tuple[bytes, PartsDue | None, dict[str, SnapshotPart] | None]:
        """With every answer in, the sim's own state, then every node asked for its part (also when either failed:
        a node told of this tick holds what comes until it is asked). The parts are gathered while the line goes
        on (`PartsDue`), unless a node was not told of this tick ahead (one asked for now): then the line waits."""
        sim = self.sim
        try:
            asks, nodes, lost = lockstep_asks(sim, self._stage)
        except SnapshotFailed:
            publish_asks(sim, asks_at_boundary(sim))
            raise
        try:
            own = self._own_state()  # before the nodes are asked: they write theirs while the line goes on
        finally:
            due = PartsDue(sim, asks, nodes, self.starts.now(sim.bus))
            self._stage("ask")
        if lost:
            raise SnapshotFailed(f"the controllers of {', '.join(lost)} are lost")
        if all(sim.outputs.told.get(node) == due.tick for node in due.nodes):
            return own, due, None
        due.wait()
        self._stage("nodes")
        return own, None, due.parts()

    def pump(self) -> None:
        """At each tick boundary: the parts of the snapshot being gathered taken in (the file written once all are),
        and what the last snapshots cost the ticks after them measured."""
        tick = self.sim.world.tick
        self._next_ticks.at_boundary()
        if tick > self.last_tick:
            self.build_spare()  # the next snapshot's world, once the line goes on (its thread takes the GIL at first)
        for cost in list(self._costs):
            extra = cost.extra_s(tick)
            if extra is not None:
                self._add_cost(cost, extra)
        if self._pending is not None:
            due = self._pending[0]
            try:
                due.take_arrived()
            except SnapshotFailed as exc:
                self._pending = None
                self._failed(due.tick, exc)
                return
            if due.complete:
                self._complete_pending()

    def _add_cost(self, cost: CostDue, extra_s: float) -> None:
        self._costs.remove(cost)
        self.next_ticks_s.append(extra_s)

    def _complete_pending(self) -> None:
        """The snapshot being gathered, once every part is in (waited for), written; or counted as failed."""
        if self._pending is None:
            return
        (due, facts), self._pending = self._pending, None
        try:
            due.wait()
            parts = due.parts()
        except SnapshotFailed as exc:
            self._failed(due.tick, exc)
            return
        self._write_file(facts, parts)

    def _failed(self, tick: int, exc: Exception) -> None:
        self.failed.append(f"tick {tick}: {exc}")
        print(f"sim_server: no snapshot at tick {tick}: {exc}", flush=True)

    def _write_file(self, facts: tuple[int, float, bytes], parts: dict[str, SnapshotPart]) -> None:
        """The snapshot of `facts` (tick, time, the sim's own state) with the nodes' `parts`, written on a thread
        of its own while the line goes on (not at all by a restored run retaking its original's)."""
        if self.directory is None:
            return
        tick, sim_time_s, own = facts
        f = self.facts
        states = {node: parts[node].state for node in ["coordinator", *self.sim.links]}  # the scene's order
        snapshot = RunSnapshot(
            f.scene_name,
            f.scene,
            self.sim.controls.mode,
            tick,
            sim_time_s,
            f.end_tick,
            f.allocator,
            states | {"sim": own},
            sorted(t for t in self.ticks if t > tick),
            self.every_ticks,
            {node: part.incarnation for node, part in parts.items()},
        )
        path = self.directory / f"snapshot-{tick:09d}{SUFFIX}"
        self._await_writer()  # one file written at a time (the spare world builds on meanwhile)
        self._writer = threading.Thread(target=self._write, args=(snapshot, path), name="snapshot-writer")
        self._writer.start()  # compressed and written while the line goes on

    def _write(self, snapshot: RunSnapshot, path: Path) -> None:
        """Compress and write one file (on the writer thread); a file that cannot be written is counted, once said."""
        t0 = time.perf_counter()
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            self.bytes_written.append(write_snapshot(snapshot, path))
        except OSError as exc:
            self.failed.append(f"tick {snapshot.tick}: cannot write {path}: {exc.strerror or exc}")
            print(f"sim_server: {self.failed[-1]}", flush=True)
            return
        self.write_ms.append(round(1e3 * (time.perf_counter() - t0), 1))
        self.written.append(str(path))

    def _await_writer(self) -> None:
        if self._writer is not None:
            self._writer.join()
            self._writer = None

    def finish(self) -> None:
        """The snapshot being gathered completed, the file being written and the spare world being built waited
        for, if any."""
        self._complete_pending()
        for cost in list(self._costs):  # the run ended before the ticks after it: as far as they went
            self._add_cost(cost, cost.extra_s(self.sim.world.tick, ended=True) or 0.0)
        self._await_writer()
        if self._builder is not None:
            self._builder.join()
            self._builder = None

    def _stage(self, name: str) -> None:
        """The time since the last stage ended, counted as `name`'s."""
        now = time.perf_counter()
        self.stages_ms[-1][name] = round(1e3 * (now - self._stage_at), 1)
        self._stage_at = now

    def _own_state(self) -> bytes:
        """The sim's own state, compressed; the sim then goes on from it read back, in a world built afresh, exactly
        as a run restored from it will (PhysX put back into a world that has run keeps articulation caches a fresh
        world does not have)."""
        sim = self.sim
        world = self._spare_world()
        self._stage("world")
        own = capture_sim(sim)
        self._stage("sim")
        sim.use_world(world)
        restore_sim(sim, own)
        self._stage("restore")
        return zlib.compress(own, 1)

    def build_spare(self) -> None:
        """Build the world the line will go on in after the next snapshot, on a thread beside the running line (a
        fresh PhysX scene of its own: the line's stepping is bit for bit the same meanwhile, tests/fleet/sim)."""
        if self._builder is None and not self._spare:
            scene = self.sim.world.scene_model
            self._builder = threading.Thread(
                target=lambda: self._spare.append(World(scene)), name="spare-world", daemon=True
            )
            self._builder.start()

    def _spare_world(self) -> World:
        """The spare world, waiting for it if it is still being built (built here if it could not be)."""
        if self._builder is not None:
            self._builder.join()
            self._builder = None
        return self._spare.pop() if self._spare else World(self.sim.world.scene_model)

    def report(self) -> dict:
        """The snapshots written and failed; how long the line stood still for the longest, by stage; their size."""
        self.finish()
        longest = max(range(len(self.stall_s)), key=self.stall_s.__getitem__, default=None)
        return {
            "snapshots": list(self.written),
            "snapshots_retaken": len(self.stall_s) if self.directory is None else 0,
            "snapshots_failed": list(self.failed),
            "snapshot_stall_ms_max": None if longest is None else round(1e3 * self.stall_s[longest], 1),
            "snapshot_stall_ms_median": _median_ms(self.stall_s),
            "snapshot_stall_ms_by_stage": {} if longest is None else self.stages_ms[longest],
            "snapshot_next_ticks_ms_median": _median_ms(self.next_ticks_s),
            "snapshot_next_ticks_ms_max": None if not self.next_ticks_s else round(1e3 * max(self.next_ticks_s), 1),
            "snapshot_bytes_max": max(self.bytes_written, default=None),
            "snapshot_write_ms_max": max(self.write_ms, default=None),
        }


def _median_ms(values: list[float]) -> float | None:
    return None if not values else round(1e3 * statistics.median(values), 1)


def sim_state(sim) -> SimState:
    """What the sim server saves: its world packed, and every component's state."""
    return SimState(
        version=VERSION,
        world=sim.world.pack_state(),
        links={name: link.state() for name, link in sim.links.items()},
        coordinator_book=sim.coord_book.state(),
        faults={name: link.state() for name, link in sim.faults.items()},
        tracked=sim.tracked.state(),
        watcher=sim.watcher.state(),
        stats=sim.stats.state(),
        inputs=sim.inputs.state(),
        outputs=sim.outputs.state(),
        event_log=list(sim.event_log),
        assign_seqs=dict(sim.assign_seqs),
        estop=sim.controls.estop,
        paused=sim.controls.paused,
        started=sim.controls.started,
        drops=sim.drops.state(),
    )


def capture_sim(sim) -> bytes:
    """The sim server's state as bytes."""
    try:
        return pack(sim_state(sim))
    except SavedStateError as exc:
        raise StateError(str(exc)) from None


def restore_sim(sim, part: bytes) -> None:
    """Put a state from `capture_sim` back into a sim server of the same scene (its components in place)."""
    state = read_sim_state(part)
    try:
        _put_back(sim, state)
    except (ValueError, KeyError) as exc:  # a state of other arms, or of values no run has
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise StateError(f"cannot put back the state of the sim: {first}") from None


def _put_back(sim, state: SimState) -> None:
    sim.world.restore_state(state.world)
    for name, link in sim.links.items():
        link.restore(state.links[name])
    sim.coord_book.restore(state.coordinator_book)
    for name, link in sim.faults.items():
        link.restore(state.faults[name])
    sim.tracked.restore(state.tracked)
    sim.watcher.restore(state.watcher)
    sim.stats.restore(state.stats)
    sim.inputs.restore(state.inputs)
    sim.outputs.restore(state.outputs)
    sim.event_log[:] = state.event_log  # in place: the inputs and outputs hold these
    sim.assign_seqs.clear()
    sim.assign_seqs.update(state.assign_seqs)
    sim.controls.estop, sim.controls.paused, sim.controls.started = state.estop, state.paused, state.started
    sim.drops.restore(state.drops)


def forget_wall_clock_flights(sim) -> None:
    """A sim restored from a realtime run's snapshot: the states, frames and messages it had in flight were timed on
    that run's wall clock and its answers applied on arrival; none of them is awaited or delivered here."""
    sim.coord_book.clear()
    for link in sim.links.values():
        link.book.clear()
    sim.inputs.delayed.put_back([], 0)
