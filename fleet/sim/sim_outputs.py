"""The sim server's outputs: goal results, line events, the states due (with the parts), the coordinator's frames,
the monitors' view and the status, each put in flight on its link and sent when it arrives."""

from __future__ import annotations

import math
import time

import msgspec
import numpy as np

from fleet.bus.codec import encode
from fleet.bus.flights import FlightBook
from fleet.bus.goals import result_message
from fleet.bus.lockstep import ArmLink
from fleet.bus.messages import ArmState, LineEvent, LineView, SimStatus
from fleet.sim.line_controls import LineControls
from fleet.sim.line_watch import LineWatcher
from fleet.sim.sim_bus import SimBus
from fleet.sim.sim_cadence import SimCadence
from fleet.sim.sim_stats import SimStats
from fleet.sim.tracking import TrackedArms
from fleet.sim.world import PartInfo, World
from fleet.sim.world_messages import arm_state, parts_state
from robots.joint_trajectory import GoalResult
from robots.phase import Phase
from robots.saved_state import SavedState, generator_of, generator_state

STATUS_PERIOD_S = 0.25  # wall seconds between `SimStatus` messages


VIEW_MAX_WALL_HZ = 60.0  # views for watchers (monitors, ROS front ends), at most this often in wall time


class OutputsState(SavedState, frozen=True):
    """What `SimOutputs` saves: its noise stream, the newest parts message's tick, what each node was told of the
    next snapshot, and its wall-clock stamps (this process's clock)."""

    noise: str  # the pose noise generator's state
    status_at_s: float
    parts_tick: int
    told: dict[str, int]
    view_at_s: float


class SimOutputs:
    """What goes out of one sim server: of its `world`, the arms' `links` and `tracked` trackers, the line `watcher`'s
    events (kept in `event_log`), the orders announced (`assign_seqs`), on `bus`."""

    def __init__(
        self,
        world: World,
        bus: SimBus,
        controls: LineControls,
        cadence: SimCadence,
        links: dict[str, ArmLink],
        coord_book: FlightBook,
        tracked: TrackedArms,
        stats: SimStats,
        watcher: LineWatcher,
        event_log: list[LineEvent],
        assign_seqs: dict[str, int],
    ) -> None:
        self.world, self.bus, self.controls, self.cadence = world, bus, controls, cadence
        self.links, self.coord_book, self.tracked, self.stats = links, coord_book, tracked, stats
        self.watcher, self.event_log, self.assign_seqs = watcher, event_log, assign_seqs
        # pose noise: repeats for a seed
        self._noise_rng = np.random.default_rng([world.scene_model.seed, 0x401_5E])
        self._status_at = 0.0
        self.parts_tick = -1  # of the newest parts message published
        self.told: dict[str, int] = {}  # by node: the next snapshot's tick named in the newest state or frame sent it
        self._view_at = -math.inf  # wall time of the last view built
        # `--perception cameras`: the controllers and the coordinator get no part poses (perception's instead); the
        # monitors' view still shows the truth
        self.blind = False

    def use_world(self, world: World) -> None:
        self.world = world

    def state(self) -> OutputsState:
        return OutputsState(
            noise=generator_state(self._noise_rng),
            status_at_s=self._status_at,
            parts_tick=self.parts_tick,
            told=dict(self.told),
            view_at_s=self._view_at,
        )

    def restore(self, state: OutputsState) -> None:
        self._noise_rng = generator_of(state.noise)
        self._status_at, self.parts_tick, self._view_at = state.status_at_s, state.parts_tick, state.view_at_s
        self.told = dict(state.told)

    def results(self, arm: str, results: list[GoalResult]) -> None:
        for r in results:
            self.stats.results[r.status.value] += 1
            self.bus.put(self.bus.result_pubs[arm], "result", encode(result_message(arm, r)))

    def events(self, parts: list[PartInfo]) -> bool:
        """This tick's line events (parts arrived, resting at a station, lost, retired), before the states.
        True when some part left the stage (lost or retired), so `parts` is out of date."""
        left = False
        for e in self.watcher.update(self.world, parts):
            event = LineEvent(e.kind, e.part_id, e.tick, e.detail, e.type_index)
            self.event_log.append(event)
            self.bus.put(self.bus.events_pub, "events", encode(event))
            left = left or e.kind in ("lost", "retired")
        return left

    def _state(self, name: str, snapshot_tick: int) -> ArmState:
        link, tracker = self.links[name], self.tracked.trackers[name]
        step = link.last_step
        desired_q, desired_dq = tracker.desired_now
        last = tracker.last
        return arm_state(
            self.world,
            name,
            held=self.controls.estop or link.lost or link.watchdog_held or self.tracked.taken(name),
            taken=self.tracked.taken(name),
            lost=link.lost,
            task_id=step.task_id if step else None,
            phase=step.phase if step else Phase.IDLE,
            progress=step.progress if step else 0.0,
            assign_seq=self.assign_seqs[name] if self.controls.coordinator and self.controls.lockstep else -1,
            failure=step.failure if step else "",
            failure_code=step.failure_code if step else "",
            request_seq=step.request_seq if step else 0,
            request_q_to=step.request_q_to if step else (),
            request_duration_s=step.request_duration_s if step else 0.0,
            request_then_q=step.request_then_q if step else (),
            request_then_after_s=step.request_then_after_s if step else (),
            goal_id=tracker.goal_id,
            desired_q=tuple(map(float, desired_q)),
            desired_dq=tuple(map(float, desired_dq)),
            result_goal_id=last.goal_id if last else 0,
            result_status=last.status.value if last else "",
            result_code=int(last.code) if last else 0,
            result_reason=last.reason if last else "",
            next_tick=link.next_tick,
            period_ticks=link.period_ticks,
            snapshot_tick=snapshot_tick,
        )

    def states(self, due: list[ArmLink], parts: list[PartInfo] | None = None, snapshot_tick: int = -1) -> None:
        """States sampled for the controllers due now (and the parts with them), those arriving now sent; the
        coordinator's frame likewise; the monitors' view. Each names `snapshot_tick`, the run's next snapshot
        (-1: none due), so that its node holds what comes from then on (`fleet.snapshot.snapshot_link`)."""
        w, bus = self.world, self.bus
        tick = w.tick
        for link in due:  # a lost controller keeps getting states at its rate, so it can answer and rejoin
            link.next_tick = tick + link.period_ticks
        frame = self.controls.coordinator and tick % self.cadence.coord_period_ticks == 0
        pausing = tick in self.controls.pause_at_ticks  # the line stands after this tick: its watchers see it
        view_tick = pausing or tick % self.cadence.view_every_ticks == 0
        view = view_tick and bus.watched() and (pausing or self._view_due())  # only while watched
        if due or frame or view:
            names = list(w.arms) if (frame or view) else [link.name for link in due]
            states = {name: self._state(name, snapshot_tick) for name in names}
            now = time.monotonic()
            for link in due:
                if self.controls.controllers:  # someone must answer it (else the states are feedback only)
                    link.book.send(tick, states[link.name], link.period_ticks, now, self.controls.deferred)
                else:
                    bus.put(bus.state_pubs[link.name], "state", encode(states[link.name]))
            parts = w.active_parts() if parts is None else parts
            parts_msg = parts_state(w, parts, len(self.event_log))
            told = parts_state(w, [], len(self.event_log)) if self.blind else parts_msg
            if due:
                seen = self._with_noise(told) if w.scene_model.part_pose_noise_m > 0 else told
                bus.put(bus.parts_pub, "parts", encode(seen))
                self.parts_tick = tick
            if frame or view:
                arms = tuple(states.values())
                if frame:
                    line = LineView(tick, w.sim_time_s, arms, told, snapshot_tick=snapshot_tick)
                    self.coord_book.send(tick, line, 1, now, self.controls.deferred_coord)
                if view:
                    bus.put(bus.view_pub, "view", encode(LineView(tick, w.sim_time_s, arms, parts_msg)))
        self._deliver()

    def _view_due(self) -> bool:
        """A view at most `VIEW_MAX_WALL_HZ` times a wall second: watchers draw no faster, and a lockstep line runs
        ten times real time (views feed only watchers: the coordinator's frames, and the line, never depend on them)."""
        now = time.monotonic()
        if now - self._view_at < 1.0 / VIEW_MAX_WALL_HZ:
            return False
        self._view_at = now
        return True

    def _deliver(self) -> None:
        """Send what reaches its process now: states (a delayed one stamped with the tick it arrives), frames."""
        tick, now, bus = self.world.tick, time.monotonic(), self.bus
        for link in self.links.values():
            flight = link.book.deliver(tick, now, self.controls.deferred)
            if flight is not None:
                state = flight.message
                if flight.tick != tick:
                    state = msgspec.structs.replace(state, delivered_tick=tick)
                flight.payload = encode(state)
                bus.put(bus.state_pubs[link.name], "state", flight.payload)
                self.told[link.name] = state.snapshot_tick
            elif not self.controls.deferred:
                link.book.prune(tick, self.cadence.max_period_ticks)
        flight = self.coord_book.deliver(tick, now, self.controls.deferred_coord)
        if flight is not None:
            line = flight.message
            if flight.tick != tick:  # the events published meanwhile come before it: the coordinator waits for them
                parts = msgspec.structs.replace(line.parts, events_published=len(self.event_log))
                line = msgspec.structs.replace(line, parts=parts, delivered_tick=tick)
            flight.payload = encode(line)
            bus.put(bus.frame_pub, "frame", flight.payload)
            self.told["coordinator"] = line.snapshot_tick
        elif not self.controls.deferred_coord:
            self.coord_book.prune(tick, self.cadence.max_period_ticks)

    def _with_noise(self, parts):
        """The parts as controllers see them in a randomised scene: positions with seeded Gaussian noise."""
        noise = self._noise_rng.normal(0.0, self.world.scene_model.part_pose_noise_m, len(parts.positions))
        return msgspec.structs.replace(parts, positions=tuple(float(p + n) for p, n in zip(parts.positions, noise)))

    def status(self, force: bool = False) -> None:
        """The clock's settings and running figures, every `STATUS_PERIOD_S` of wall time."""
        now = time.monotonic()
        if not force and now - self._status_at < STATUS_PERIOD_S:
            return
        self._status_at = now
        st, ticks = self.stats, max(self.stats.ticks, 1)
        recent = st.recent_round_trip_ms
        status = SimStatus(
            self.world.tick,
            self.world.sim_time_s,
            self.controls.mode,
            self.controls.paused,
            self.controls.estop,
            self.controls.speed,
            tuple(st.busy_ticks[a] / ticks for a in self.links),
            float(np.percentile(np.asarray(recent), 99)) if recent else 0.0,
            st.contact_ticks,
            st.last_contact_pairs,
            st.last_contact_s,
            tuple(link.name for link in self.links.values() if link.lost),
            self.bus.drops.total,
        )
        self.bus.put(self.bus.status_pub, "status", encode(status))
