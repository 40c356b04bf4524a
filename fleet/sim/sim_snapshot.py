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

import pickle
import threading
import time
import zlib
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from fleet.sim.snapshot_asks import SnapshotFailed, node_states
from fleet.sim.world import World
from fleet.snapshot.process_state import StateError, capture, restore
from fleet.snapshot.snapshot_file import SUFFIX, RunSnapshot, SceneSource, write_snapshot

# the sim's attributes that belong to this process alone: its bus, its physics world (packed apart), its stop flag,
# and how it was started (clock, speed, timeouts, who it waits for: a restored run may be started otherwise)
SIM_LIVE = (
    "world",
    "bus",
    "drops",
    "stop",
    "spool",
    "target_log",
    "snapshots",
    "snapshot_asked_by",
    "snapshots_refused",
    "restored_from",
    "mode",
    "speed",
    "barrier",
    "watchdog_s",
    "lockstep_timeout_s",
    "controllers",
    "coordinator",
    "count_contacts",
)


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
    stall_s: list[float] = field(default_factory=list)
    stages_ms: list[dict[str, float]] = field(default_factory=list)  # each snapshot's stall, by stage
    bytes_written: list[int] = field(default_factory=list)
    write_ms: list[float] = field(default_factory=list)  # compressing and writing each file (the line goes on)
    _stage_at: float = 0.0
    _writer: threading.Thread | None = None
    _builder: threading.Thread | None = None  # building the spare world
    _incarnations: dict = field(default_factory=dict)  # of the nodes, at the last snapshot
    _spare: list = field(default_factory=list)  # the world the line goes on in after the next snapshot
    last_tick: int = 0  # the tick of the last snapshot taken (or restored from): never twice at one tick

    def due(self, tick: int) -> bool:
        """Whether a snapshot is scheduled at this tick (never twice at one)."""
        every = self.every_ticks > 0 and tick % self.every_ticks == 0
        return tick != self.last_tick and tick > 0 and (tick in self.ticks or every)

    def take(self) -> Path | None:
        """The run's snapshot at this tick boundary, written; None (the reason counted and printed) if it failed.
        The line goes on either way."""
        t0 = self._stage_at = time.perf_counter()
        self.stages_ms.append({})
        sim = self.sim
        self.last_tick = sim.world.tick
        try:
            states = self._gather()
        except (SnapshotFailed, StateError) as exc:
            self.failed.append(f"tick {sim.world.tick}: {exc}")
            print(f"sim_server: no snapshot at {sim.world.sim_time_s:.2f} s: {exc}", flush=True)
            return None
        self.stall_s.append(time.perf_counter() - t0)
        if self.directory is None:  # a restored run retaking its original's snapshots: the line, not the file
            return None
        f, tick = self.facts, sim.world.tick
        snapshot = RunSnapshot(
            f.scene_name,
            f.scene,
            sim.mode,
            tick,
            sim.world.sim_time_s,
            f.end_tick,
            f.allocator,
            states,
            sorted(t for t in self.ticks if t > tick),
            self.every_ticks,
            self._incarnations,
        )
        path = self.directory / f"snapshot-{tick:09d}{SUFFIX}"
        self._await_writer()  # one file written at a time (the spare world builds on meanwhile)
        self._writer = threading.Thread(target=self._write, args=(snapshot, path), name="snapshot-writer")
        self._writer.start()  # compressed and written while the line goes on
        return path

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
        """Wait for the snapshot file being written and the spare world being built, if any."""
        self._await_writer()
        if self._builder is not None:
            self._builder.join()
            self._builder = None

    def _stage(self, name: str) -> None:
        """The time since the last stage ended, counted as `name`'s."""
        now = time.perf_counter()
        self.stages_ms[-1][name] = round(1e3 * (now - self._stage_at), 1)
        self._stage_at = now

    def _gather(self) -> dict[str, bytes]:
        sim = self.sim
        parts = node_states(sim, self._stage)
        self._incarnations = {node: part.incarnation for node, part in parts.items()}
        states = {node: parts[node].state for node in ["coordinator", *sim.links]}  # the scene's order, not arrival
        world = self._spare_world()
        self._stage("world")
        own = capture_sim(sim)
        states["sim"] = zlib.compress(own, 1)
        self._stage("sim")
        # go on from the state written, in a world built afresh, exactly as a run restored from it will (PhysX put
        # back into a world that has run keeps articulation caches a fresh world does not have)
        sim.world = world
        restore_sim(sim, own)
        self.build_spare()  # the next snapshot's, while the line goes on
        self._stage("restore")
        return states

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
            "snapshot_stall_ms_by_stage": {} if longest is None else self.stages_ms[longest],
            "snapshot_bytes_max": max(self.bytes_written, default=None),
            "snapshot_write_ms_max": max(self.write_ms, default=None),
        }


def capture_sim(sim) -> bytes:
    """The sim server's state: its world packed, every other attribute but its live handles."""
    blob = capture(sim, SIM_LIVE, live={"world": sim.world, "server": sim})
    return pickle.dumps(
        {"world": sim.world.pack_state(), "server": blob, "drops": dict(sim.drops.counts)},
        protocol=pickle.HIGHEST_PROTOCOL,
    )


def restore_sim(sim, part: bytes) -> None:
    """Put a state from `capture_sim` back into a sim server of the same scene."""
    try:
        saved = pickle.loads(part)
    except Exception as exc:  # noqa: BLE001 - any fault of a foreign blob is one line
        raise StateError(f"cannot read back the sim's state: {exc}") from exc
    sim.world.restore_state(saved["world"])
    restore(sim, saved["server"], live={"world": sim.world, "server": sim})
    sim.drops.counts = Counter(saved["drops"])
    sim.bus.stats = sim.stats  # the bus counts what it sends in the sim's figures


def forget_wall_clock_flights(sim) -> None:
    """A sim restored from a realtime run's snapshot: the states, frames and messages it had in flight were timed on
    that run's wall clock and its answers applied on arrival; none of them is awaited or delivered here."""
    sim.coord_book.clear()
    for link in sim.links.values():
        link.book.clear()
    sim.delayed = type(sim.delayed)()
