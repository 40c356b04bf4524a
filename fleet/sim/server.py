"""The sim server: the physics world and every arm's trajectory tracker behind the bus, one tick at a time.

Its inputs (`fleet.sim.sim_inputs`), outputs (`fleet.sim.sim_outputs`), lockstep links and barrier
(`fleet.bus.lockstep`), bus handles (`fleet.sim.sim_bus`) and counts (`fleet.sim.sim_stats`) live apart; this
class ties them to the physics: a tick takes the answers due, sends the states due, tracks and steps.
The process around it is `fleet.nodes.sim_server`.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Callable

import zenoh

from fleet.bus.faults import faults_report, links_for
from fleet.bus.flights import FlightBook
from fleet.bus.keys import Keys
from fleet.bus.lockstep import ArmLink, Barrier
from fleet.bus.messages import EventLog, LineEvent
from fleet.common.processes import StopFlag
from fleet.record.spool import BusSpool
from fleet.sim.line_controls import LineControls
from fleet.sim.line_watch import LineWatcher
from fleet.sim.realtime_clock import ClockFigures, RealtimePacing, spread_ms
from fleet.sim.sim_bus import SimBus
from fleet.sim.sim_cadence import SimCadence
from fleet.sim.sim_inputs import SimInputs
from fleet.sim.sim_lockstep import SimLockstep
from fleet.sim.sim_outputs import SimOutputs
from fleet.sim.sim_stats import SimStats
from fleet.sim.tracking import TrackedArms
from fleet.sim.world import World
from robots.phase import IDLE_PHASES
from robots.tracker import WATCHDOG_REASON

COORDINATOR_TIMEOUT_S = 3.0  # wall seconds a lockstep frame waits for a silent coordinator: a decision may search for
# reach near the edge of a short arm's (an SO-101's new spot: up to ~0.4 s measured; more on a loaded machine)
LOCKSTEP_TIMEOUT_S = 3.0  # wall seconds a lockstep tick waits for a silent controller before its arm is lost: it only
# ends the wait for a dead or hung process (the line's outcome is the same tick either way), and a controller starved
# of the CPU for over 1 s (two restored lines beside training examples on 2 cores) lost its arm at the 1 s this was


class SimServer:
    """Runs a world behind the bus; call `run_ticks` (or `tick` repeatedly).

    `controllers=False` waits for nobody: the arms take goals from whoever sends them (a user's own
    trajectory client), with no watchdog. It wires its parts: `controls` (the line's switches), `inputs`,
    `outputs` and `lockstep` around the arms' `links`, the coordinator's `coord_book` and the `tracked` arms."""

    def __init__(
        self,
        world: World,
        session: zenoh.Session,
        keys: Keys,
        *,
        mode: str = "lockstep",
        watchdog_s: float = 0.25,
        lockstep_timeout_s: float = LOCKSTEP_TIMEOUT_S,
        coordinator_timeout_s: float | None = None,
        first_command_timeout_s: float = 30.0,
        coordinator: bool = False,
        controllers: bool = True,
        count_contacts: bool = True,
        stop: StopFlag | None = None,
        speed: float = 1.0,
    ) -> None:
        self.controls = LineControls(mode, controllers, coordinator, speed=speed, started=not controllers)
        self.world, self.keys, self.stop = world, keys, stop
        self.count_contacts = count_contacts
        scene = world.scene_model
        self.cadence = cadence = SimCadence.of(scene)
        self.faults = links_for(scene.network, [*world.arms, "coordinator"], scene.seed)
        hz = cadence.control_hz
        self.links = {n: ArmLink(n, cadence.decision_ticks, FlightBook(self.faults[n], hz)) for n in world.arms}
        self.coord_book = FlightBook(self.faults["coordinator"], hz)
        self.tracked = TrackedArms(world)
        self.stats = SimStats()
        self.event_log: list[LineEvent] = []  # every event published, in order (a respawned coordinator rebuilds)
        history = lambda: EventLog(self.world.tick, tuple(self.event_log))
        self.bus = SimBus(session, keys, list(world.arms), scene.model_dump_json(), history, self.stats)
        self.drops = self.bus.drops
        self.watcher = LineWatcher(scene)
        self.assign_seqs = {name: 0 for name in world.arms}
        self.target_log: list | None = None  # with `record_targets`: every tick's drive targets, for a replay baseline
        self.spool: BusSpool | None = None  # with `--spool`: what the bus carries, appended between ticks
        self.snapshots = None  # with `--snapshot-at/--snapshot-every`: a `fleet.sim.sim_snapshot.SimSnapshots`
        self.restored_from: dict | None = None  # from a snapshot: its tick, wall s until every node was back
        self.snapshots_refused: list[str] = []  # snapshots asked for that this run cannot take, and why
        self.cameras = None  # with `--cameras`: a `fleet.sim.cameras.line_cameras.LineCameras`
        self.clock = ClockFigures()  # realtime: how well the wall clock was kept
        self.scheduling = "normal"  # the sim process's scheduling (`--rt`: SCHED_FIFO where allowed)
        self._wire(watchdog_s, lockstep_timeout_s, first_command_timeout_s, coordinator_timeout_s)

    def _wire(
        self,
        watchdog_s: float,
        lockstep_timeout_s: float,
        first_command_timeout_s: float,
        coordinator_timeout_s: float | None,
    ) -> None:
        """The inputs, outputs and lockstep, each handed what it uses."""
        world, bus, controls, cadence = self.world, self.bus, self.controls, self.cadence
        links, coord_book, tracked, stats = self.links, self.coord_book, self.tracked, self.stats
        self.outputs = SimOutputs(
            world, bus, controls, cadence, links, coord_book, tracked, stats, self.watcher, self.event_log,
            self.assign_seqs,
        )  # fmt: skip
        self.inputs = SimInputs(
            world, bus, controls, cadence, links, coord_book, tracked, self.outputs, stats, self.assign_seqs,
            watchdog_s,
        )  # fmt: skip
        # how long a lockstep frame waits for the coordinator (longer when a crashed one is respawned: the line holds)
        if coordinator_timeout_s is None:
            coordinator_timeout_s = max(lockstep_timeout_s, COORDINATOR_TIMEOUT_S)
        barrier = Barrier(lockstep_timeout_s, first_command_timeout_s, coordinator_timeout_s)
        self.lockstep = SimLockstep(
            barrier, bus, controls, links, coord_book, self.inputs, self.outputs, tracked, stats, self.stop
        )

    def use_world(self, world: World) -> None:
        """Go on in `world`, a world of the same scene built afresh (after a snapshot); its state is put in after."""
        self.world = world
        self.tracked.use_world(world)
        self.inputs.use_world(world)
        self.outputs.use_world(world)
        if self.cameras is not None:
            self.cameras.rig.use_world(world)

    def close(self) -> None:
        if self.cameras is not None:
            self.cameras.close()
        self.bus.close()

    def settle(self) -> None:
        """After the last tick: the answers to what was delivered awaited (`SimLockstep.settle`, in lockstep) and
        perception's to the last frames."""
        self.lockstep.settle()
        if self.cameras is not None:
            self.cameras.settle()

    # --- one tick -------------------------------------------------------------------
    def tick(self) -> None:
        """Events; answers due now (waiting in lockstep); due states and frames out; track; step the physics."""
        clock = self.stats.wall_s
        t0 = time.perf_counter()
        parts = None
        if self.world.tick % self.cadence.decision_ticks == 0:  # the line's events at the controllers' default rate
            parts = self.world.active_parts()
            if self.outputs.events(parts):
                parts = self.world.active_parts()  # parts lost or retired just now are off the stage
        due = [link for link in self.links.values() if link.next_tick <= self.world.tick]
        t1 = time.perf_counter()
        started = self.controls.started
        self._take_answers_due()
        waited = t2 = time.perf_counter()
        if self.cameras is not None:  # the world as this tick's states show it, rendered while the controllers wait
            self.cameras.tick(self.world.tick, len(self.event_log))  # for them (not while they compute their answers)
            t2 = time.perf_counter()
            clock["cameras"] += t2 - waited
        self.outputs.states(due, parts, self._next_snapshot_tick())
        t3 = time.perf_counter()
        self._step_physics()
        t4 = time.perf_counter()
        self.stats.ticks += 1
        if self.count_contacts:
            self.stats.contacts(self.world.inter_arm_contacts(), self.world.sim_time_s)
        t5 = time.perf_counter()
        clock["publish"] += (t1 - t0) + (t3 - t2)
        clock["wait" if started else "startup"] += waited - t1  # until every process answered once: start-up
        clock["physics"] += t4 - t3
        clock["contacts"] += t5 - t4

    def _take_answers_due(self) -> None:
        """The answers due at this tick: awaited (lockstep, or until every process is up), else whatever came in."""
        tick, controls = self.world.tick, self.controls
        links = []
        if controls.deferred:
            links = [
                link
                for link in self.links.values()
                if link.next_tick <= tick or link.book.arrives(tick) or link.book.applies(tick)
            ]
        # the coordinator's answers take effect with the next states out after them (frames: its period apart)
        frame = controls.coordinator and tick % self.cadence.coord_period_ticks == 0
        coord = controls.deferred_coord and (
            frame or self.coord_book.arrives(tick) or (bool(links) and self.coord_book.applies(tick))
        )
        if links or coord:
            self.lockstep.wait_for_answers(links, coord, tick)
        else:
            self.inputs.take()

    def _next_snapshot_tick(self) -> int:
        """The tick of the run's next snapshot after this one, told to every node with its states and frames; -1:
        none due, or not lockstep (a realtime line is paused for a snapshot)."""
        if self.snapshots is None or not self.controls.lockstep:
            return -1
        return self.snapshots.next_due(self.world.tick)

    def _step_physics(self) -> None:
        """The trackers write their drive targets, the physics steps a tick, and the trackers' results go out."""
        self.tracked.apply()
        if self.target_log is not None:
            self.target_log.append([a.written_targets() for a in self.world.arms.values()])
        self.world.step()
        for name, rs in self.tracked.update().items():
            if any(r.reason == WATCHDOG_REASON for r in rs):
                self.links[name].watchdog_held = True
                self.stats.watchdog_holds[name] += 1
            self.outputs.results(name, rs)
        for name, link in self.links.items():
            if link.last_step is not None and link.last_step.phase not in IDLE_PHASES and not link.lost:
                self.stats.busy_ticks[name] += 1
                if link.last_step.request_seq > 0:
                    self.stats.grant_wait_ticks[name] += 1

    def _snapshot_if_due(self, before_take: Callable[[], None] = lambda: None) -> bool:
        """A snapshot due now (`--snapshot-at/--snapshot-every`) or asked for (`SimControl.snapshot`) is taken here,
        at the tick boundary (the parts of one taken earlier taken in); one asked of a run with nowhere to write it
        is refused, and the refusal counted. `before_take` is called just before one is taken."""
        asked, self.controls.snapshot_asked_by = self.controls.snapshot_asked_by, ""
        if self.snapshots is not None:
            self.snapshots.pump()  # the parts of one taken before, and what it cost the ticks after it
        if self.snapshots is None:
            if asked:
                self.snapshots_refused.append(f"{asked}: this run writes no snapshots (fleet run --out DIR)")
            return False
        if asked or self.snapshots.due(self.world.tick):
            before_take()
            self.snapshots.take()
            return True
        return False

    def announce_the_rest(self) -> None:
        """After the last tick: the line's events since the last watch (a part released in the last ticks would
        otherwise never be announced as arrived)."""
        self.outputs.events(self.world.active_parts())

    def run_ticks(self, ticks: int, speed: float | None = None, stop: StopFlag | None = None) -> None:
        """Run `ticks` ticks (or until `stop`); in realtime mode paced by the wall clock at the speed factor.

        A pause (`SimControl`) stops the clock between ticks; the pacing restarts from where it stood."""
        stop = stop or self.stop
        controls = self.controls
        if speed is not None:
            controls.speed = speed
        pace = RealtimePacing(
            lambda: self.world.sim_time_s,
            lambda: (controls.speed, controls.started),
            self.bus.inbox.wait,
            self.stats.wall_s,
            self.clock,
        )
        try:
            self._run_paced(ticks, stop, pace)
        finally:
            pace.close()

    def _run_paced(self, ticks: int, stop: StopFlag | None, pace: RealtimePacing) -> None:
        controls = self.controls
        done = 0
        while done < ticks:
            if stop is not None and stop.should_stop():
                return
            self.outputs.status()
            if self.spool is not None:
                self.spool.pump()
            if controls.paused:
                self.inputs.take()
                self._snapshot_if_due()  # a paused line may be snapshotted: it stands still already
                self.bus.inbox.wait(0.05)
                pace.restart()
                continue
            if self._snapshot_if_due(before_take=pace.restart):
                pace.restart(measure=False)  # realtime: the line stood still for it; the clock goes on from here
            self.tick()
            done += 1
            if controls.pause_if_due(self.world.tick - 1):  # that tick's views are out: /clock reads its second
                self.outputs.status(force=True)  # the line says it paused; it goes on from the next tick
            if stop is not None and stop.should_stop():
                return
            if self.stats.coordinator_lost and controls.lockstep:
                return  # its decisions would never be announced again: end the run rather than stall it
            if not controls.lockstep:
                pace.wait()
        self.outputs.status(force=True)

    def report(self) -> dict:
        """The sim's part of the run summary."""
        arms, sim_s, feeders = list(self.links), self.world.sim_time_s, self.world.feeders
        return (
            {
                "ticks": self.stats.ticks,
                "sim_seconds": round(sim_s, 6),
                "parts_spawned": sum(c.spawned for c in feeders),
                "feeder_full_skips": sum(c.skipped_full for c in feeders),
                "feeder_held_s": {c.feeder.name: round(c.held_s, 2) for c in feeders if c.held_s > 0},
                "events": dict(sorted(Counter(e.kind for e in self.event_log).items())),
            }
            | self.stats.summary(arms, sim_s)
            | {
                "dropped_messages": self.drops.total,
                "refused_messages": self.drops.kinds(),
                "clamped_commands": {a: t.clamped for a, t in self.tracked.trackers.items() if t.clamped},
                **self.tracked.safety.report(),
            }
            | self.stats.outcome(arms, sim_s)
            | {"randomised": dict(self.world.scene_model.randomised), "network_faults": faults_report(self.faults)}
            | self.stats.wall_clock()
            | (self.snapshots.report() if self.snapshots is not None else {})
            | {"restored_from": self.restored_from, "snapshots_refused": list(self.snapshots_refused)}
            | {"realtime_clock": self._clock_report()}
            | ({"cameras": self.cameras.counts.report()} if self.cameras is not None else {})
            | ({"seen": self.cameras.score.report()} if self.cameras is not None and self.cameras.score else {})
        )

    def _clock_report(self) -> dict | None:
        """Realtime: how well the wall clock was kept (`ClockFigures`), how long the controllers took to answer each
        state, and the scheduling the sim ran at; None in lockstep (its clock is the barrier's)."""
        if self.controls.lockstep:
            return None
        answers = spread_ms(self.stats.round_trip_ms)
        return self.clock.report(self.controls.speed) | {
            "controller_answer_ms": answers,
            "sim_scheduling": self.scheduling,
        }
