"""The sim server's inputs: e-stop, clock controls, controllers' answers and goals, the coordinator's ticks,
decoded and checked; in lockstep held for their due tick, in realtime applied when they arrive (after the
link's injected delay)."""

from __future__ import annotations

import dataclasses
import math
import time

from fleet.bus.faults import DelayLine
from fleet.bus.flights import FlightBook, FlightState, flight_of, flight_state
from fleet.bus.goals import goal_from_message
from fleet.bus.keys import Keys
from fleet.bus.lockstep import ArmLink
from fleet.bus.message_checks import request_problem
from fleet.bus.messages import ArmGoalMsg, ArmState, ControllerStep, CoordTick
from fleet.sim.line_controls import LineControls
from fleet.sim.sim_bus import SimBus, control_problem, coord_tick_problem
from fleet.sim.sim_cadence import SimCadence
from fleet.sim.sim_outputs import SimOutputs
from fleet.sim.sim_stats import SimStats
from fleet.sim.tracking import TrackedArms
from fleet.sim.world import World
from robots.joint_trajectory import GoalResult
from robots.saved_state import SavedState


class DelayedState(SavedState, frozen=True):
    """Realtime: one message on its way in (`fleet.bus.faults.DelayLine`): a coordinator's tick, a goal or an
    answer's flight, for the arm named."""

    due_s: float  # this process's wall clock
    order: int
    kind: str  # coord | goal | step
    arm: str | None
    coord: CoordTick | None = None
    goal: ArmGoalMsg | None = None
    flight: FlightState[ArmState, ControllerStep] | None = None


class InputsState(SavedState, frozen=True):
    """What `SimInputs` saves: goals that came from outside clients and are not yet submitted, and (realtime) what
    is on its way in."""

    outside_goals: set[int]
    delayed: list[DelayedState]
    delayed_count: int


class SimInputs:
    """What comes in to one sim server, taken between ticks (`take`): the switches it sets in `controls`, the
    answers and goals it hands the arms' `links` and `tracked` trackers (their results out through `outputs`), the
    coordinator's ticks its `coord_book` awaits, and (realtime) what the links delay."""

    def __init__(
        self,
        world: World,
        bus: SimBus,
        controls: LineControls,
        cadence: SimCadence,
        links: dict[str, ArmLink],
        coord_book: FlightBook,
        tracked: TrackedArms,
        outputs: SimOutputs,
        stats: SimStats,
        assign_seqs: dict[str, int],
        watchdog_s: float,
    ) -> None:
        self.world, self.bus, self.controls, self.cadence = world, bus, controls, cadence
        self.links, self.coord_book = links, coord_book
        self.tracked, self.outputs, self.stats = tracked, outputs, stats
        self.assign_seqs, self.watchdog_s = assign_seqs, watchdog_s
        self.delayed = DelayLine()  # realtime: answers, goals and coordinator ticks on their way in
        self.outside_goals: set[int] = set()  # ids of goals that came on an arm's `drive` key, not yet submitted

    def use_world(self, world: World) -> None:
        self.world = world

    def state(self) -> InputsState:
        delayed = []
        for due_s, order, (kind, link, item) in self.delayed.held():
            arm = None if link is None else link.name
            carried = {"flight": flight_state(item)} if kind == "step" else {kind: item}  # a coord tick or a goal
            delayed.append(DelayedState(due_s=due_s, order=order, kind=kind, arm=arm, **carried))
        return InputsState(outside_goals=set(self.outside_goals), delayed=delayed, delayed_count=self.delayed.count)

    def restore(self, state: InputsState) -> None:
        self.outside_goals = set(state.outside_goals)
        held = []
        for d in state.delayed:
            link = None if d.arm is None else self.links[d.arm]
            item = flight_of(d.flight) if d.kind == "step" else d.coord if d.kind == "coord" else d.goal
            held.append((d.due_s, d.order, (d.kind, link, item)))
        self.delayed.put_back(held, state.delayed_count)

    def take(self) -> None:
        bus = self.bus
        for key, payload in bus.estop_inbox.drain():
            msg = bus.estop.decode(key, payload)
            if msg is not None and msg.engaged != self.controls.estop:
                self.controls.estop = msg.engaged
                self.world.belt_running = not msg.engaged  # an e-stop stops every drive of the line
                for arm, results in self.tracked.set_estop(msg.engaged).items():
                    self.outputs.results(arm, results)
        for key, payload in bus.control_inbox.drain():
            if (msg := bus.control.decode(key, payload)) is None:
                continue
            if problem := control_problem(msg):
                bus.drops.drop(key, problem)
                continue
            self.controls.paused = self.controls.paused if msg.paused is None else msg.paused
            self.controls.speed = self.controls.speed if msg.speed is None else msg.speed
            if msg.snapshot:
                self.controls.snapshot_asked_by = msg.source  # taken at the next tick boundary
        for key, payload in bus.inbox.drain():
            if key.endswith(("/goal", "/drive")):
                self._on_goal(key, payload)
            else:
                self._on_step(key, payload)
        for key, payload in bus.coord_inbox.drain():
            if (msg := bus.coord.decode(key, payload)) is None:
                continue
            if problem := coord_tick_problem(msg, list(self.links), self.assign_seqs, self.world.tick):
                bus.drops.drop(key, problem)
                continue
            self._on_coord_tick(msg)
        for kind, link, item in self.delayed.pop_due(time.monotonic()):
            self._arrived(kind, link, item)

    def apply_coord(self, msg: CoordTick) -> None:
        """The coordinator's orders up to its tick are announced in the states from now on (lockstep)."""
        if not self.controls.lockstep:
            return  # realtime: controllers act on assignments as they arrive
        for name, seq in zip(self.links, msg.assign_seqs):
            self.assign_seqs[name] = max(self.assign_seqs[name], seq)

    def apply_answer(self, link: ArmLink, msg: ControllerStep) -> None:
        """The controller's answer takes effect (its goals are with the tracker): what it does, when it wants its
        next state, the watchdog's next deadline."""
        latest = msg.tick >= link.book.newest_delivered  # no later state went out: the schedule is still its to set
        link.last_step = msg
        period = min(max(msg.next_tick - msg.tick, 1), self.cadence.max_period_ticks)
        link.period_ticks = period
        if latest:
            link.next_tick = msg.tick + period
        deadline_tick = max(link.next_tick, self.world.tick)
        self.tracked.trackers[link.name].watch(
            deadline_tick / self.cadence.control_hz + self.watchdog_s + _round_trip_s(link)
        )
        link.watchdog_held = False
        if link.lost:
            link.lost = False
            self.stats.rejoined.append(link.name)

    def _on_coord_tick(self, msg: CoordTick) -> None:
        """The coordinator answered a frame: lockstep applies it when due (`apply_coord`); realtime when it arrives."""
        if self.controls.deferred_coord:
            self.coord_book.answer(msg.tick, msg)  # one lost on the way back is dropped by the book
            return
        passage = self.coord_book.link.passage("up")  # as an arm's answer: `link.book.link`
        if not passage.lost:
            self._arrive_later("coord", None, msg, passage.delay_s)

    def _arrive_later(self, kind: str, link: ArmLink | None, item, delay_s: float) -> None:
        """Realtime: a message on its way in arrives `delay_s` from now (at once without delay)."""
        if delay_s <= 0:
            self._arrived(kind, link, item)
        else:
            self.delayed.push(time.monotonic() + delay_s, (kind, link, item))

    def _arrived(self, kind: str, link: ArmLink | None, item) -> None:
        if kind == "coord":
            self.apply_coord(item)
        elif kind == "goal":
            self.submit(link, item)
        elif link.book.applied(item):
            self.apply_answer(link, item.answer)

    def _link_for(self, key: str, arm: str) -> ArmLink | None:
        link = self.links.get(Keys.arm_of(key))
        if link is None or arm != link.name:
            self.bus.drops.drop(key, "a message for an unknown arm or on another arm's key")
            return None
        return link

    def _on_goal(self, key: str, payload: bytes) -> None:
        msg = self.bus.goal.decode(key, payload)
        if msg is None or (link := self._link_for(key, msg.arm)) is None:
            return
        self.stats.messages_in["goal"] += 1
        if key.endswith("/drive"):
            self.outside_goals.add(msg.goal_id)
        # applied with the answer naming it (or at the arm's next due tick): a lockstep run repeats
        if self.controls.deferred:
            link.hold_goal(msg)
            return
        passage = link.book.link.passage("up")
        if not passage.lost:
            self._arrive_later("goal", link, msg, passage.delay_s)

    def submit(self, link: ArmLink, msg: ArmGoalMsg) -> None:
        goal = goal_from_message(msg)
        # refused before reaching the tracker: stamped here (the tracker stamps its own)
        if isinstance(goal, GoalResult):
            self.outputs.results(link.name, [dataclasses.replace(goal, time_s=self.world.sim_time_s)])
        else:
            outside = goal.goal_id in self.outside_goals
            self.outside_goals.discard(goal.goal_id)
            self.outputs.results(link.name, self.tracked.submit(link.name, goal, outside=outside))

    def _on_step(self, key: str, payload: bytes) -> None:
        msg = self.bus.step.decode(key, payload)
        if msg is None or (link := self._link_for(key, msg.arm)) is None:
            return
        self.stats.messages_in["step"] += 1
        problem = request_problem(msg, self.world.arms[link.name].spec.arm_dof) or (
            "" if math.isfinite(msg.progress) else "an answer with a non-finite progress"
        )
        if problem:
            self.bus.drops.drop(key, problem)
            return
        flight = link.book.answer(msg.tick, msg)
        if flight is None:  # an answer to a state already answered, overtaken or never delivered
            self.bus.drops.drop(key, "an answer to no state that awaits one (repeated, late or never sent)")
            return
        self.stats.round_trip((time.monotonic() - flight.delivered_wall_s) * 1e3)
        if self.controls.deferred:
            if flight.up_lost:
                link.answer_lost(msg.goal_ids)
            return
        passage = link.book.link.passage("up")
        if not passage.lost:
            self._arrive_later("step", link, flight, passage.delay_s)


def _round_trip_s(link: ArmLink) -> float:
    """The longest a state and its answer are expected to travel on this link (latency and 3 sigma of jitter)."""
    f = link.book.link.faults
    return 2 * (f.latency_ms + 3 * f.jitter_ms) / 1e3
