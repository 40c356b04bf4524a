"""The sim server's inputs: e-stop, clock controls, controllers' answers and goals, the coordinator's ticks,
decoded and checked; in lockstep held for their due tick, in realtime applied when they arrive (after the
link's injected delay)."""

from __future__ import annotations

import dataclasses
import math
import time
from typing import TYPE_CHECKING

from fleet.bus.flights import FlightState, flight_of, flight_state
from fleet.bus.goals import goal_from_message
from fleet.bus.keys import Keys
from fleet.bus.lockstep import ArmLink
from fleet.bus.message_checks import request_problem
from fleet.bus.messages import ArmGoalMsg, ArmState, ControllerStep, CoordTick
from fleet.sim.sim_bus import control_problem, coord_tick_problem
from robots.joint_trajectory import GoalResult
from robots.saved_state import SavedState

if TYPE_CHECKING:
    from fleet.sim.server import SimServer


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
    """What comes in to one sim server, taken between ticks (`take`)."""

    def __init__(self, sim: SimServer) -> None:
        self.sim = sim
        self.outside_goals: set[int] = set()  # ids of goals that came on an arm's `drive` key, not yet submitted

    def state(self) -> InputsState:
        delayed = []
        for due_s, order, (kind, link, item) in self.sim.delayed.held():
            arm = None if link is None else link.name
            carried = {"flight": flight_state(item)} if kind == "step" else {kind: item}  # a coord tick or a goal
            delayed.append(DelayedState(due_s=due_s, order=order, kind=kind, arm=arm, **carried))
        return InputsState(outside_goals=set(self.outside_goals), delayed=delayed, delayed_count=self.sim.delayed.count)

    def restore(self, state: InputsState) -> None:
        self.outside_goals = set(state.outside_goals)
        held = []
        for d in state.delayed:
            link = None if d.arm is None else self.sim.links[d.arm]
            item = flight_of(d.flight) if d.kind == "step" else d.coord if d.kind == "coord" else d.goal
            held.append((d.due_s, d.order, (d.kind, link, item)))
        self.sim.delayed.put_back(held, state.delayed_count)

    def take(self) -> None:
        bus = self.sim.bus
        for key, payload in bus.estop_inbox.drain():
            msg = bus.estop.decode(key, payload)
            if msg is not None and msg.engaged != self.sim.estop:
                self.sim.estop = msg.engaged
                self.sim.world.belt_running = not msg.engaged  # an e-stop stops every drive of the line
                for arm, results in self.sim.tracked.set_estop(msg.engaged).items():
                    self.sim.outputs.results(arm, results)
        for key, payload in bus.control_inbox.drain():
            if (msg := bus.control.decode(key, payload)) is None:
                continue
            if problem := control_problem(msg):
                self.sim.drops.drop(key, problem)
                continue
            self.sim.paused = self.sim.paused if msg.paused is None else msg.paused
            self.sim.speed = self.sim.speed if msg.speed is None else msg.speed
            if msg.snapshot:
                self.sim.snapshot_asked_by = msg.source  # taken at the next tick boundary
        for key, payload in bus.inbox.drain():
            if key.endswith(("/goal", "/drive")):
                self._on_goal(key, payload)
            else:
                self._on_step(key, payload)
        for key, payload in bus.coord_inbox.drain():
            if (msg := bus.coord.decode(key, payload)) is None:
                continue
            if problem := coord_tick_problem(msg, list(self.sim.links), self.sim.assign_seqs, self.sim.world.tick):
                self.sim.drops.drop(key, problem)
                continue
            self._on_coord_tick(msg)
        for kind, link, item in self.sim.delayed.pop_due(time.monotonic()):
            self._arrived(kind, link, item)

    def _on_coord_tick(self, msg: CoordTick) -> None:
        """The coordinator answered a frame: lockstep applies it when due (`_apply_coord`); realtime when it arrives."""
        if self.sim.deferred_coord:
            self.sim.coord_book.answer(msg.tick, msg)  # one lost on the way back is dropped by the book
            return
        passage = self.sim.faults["coordinator"].passage("up")
        if not passage.lost:
            self._arrive_later("coord", None, msg, passage.delay_s)

    def _arrive_later(self, kind: str, link: ArmLink | None, item, delay_s: float) -> None:
        """Realtime: a message on its way in arrives `delay_s` from now (at once without delay)."""
        if delay_s <= 0:
            self._arrived(kind, link, item)
        else:
            self.sim.delayed.push(time.monotonic() + delay_s, (kind, link, item))

    def _arrived(self, kind: str, link: ArmLink | None, item) -> None:
        if kind == "coord":
            self.sim.apply_coord(item)
        elif kind == "goal":
            self.submit(link, item)
        elif link.book.applied(item):
            self.sim.apply_answer(link, item.answer)

    def _link_for(self, key: str, arm: str) -> ArmLink | None:
        link = self.sim.links.get(Keys.arm_of(key))
        if link is None or arm != link.name:
            self.sim.drops.drop(key, "a message for an unknown arm or on another arm's key")
            return None
        return link

    def _on_goal(self, key: str, payload: bytes) -> None:
        msg = self.sim.bus.goal.decode(key, payload)
        if msg is None or (link := self._link_for(key, msg.arm)) is None:
            return
        self.sim.stats.messages_in["goal"] += 1
        if key.endswith("/drive"):
            self.outside_goals.add(msg.goal_id)
        # applied with the answer naming it (or at the arm's next due tick): a lockstep run repeats
        if self.sim.deferred:
            link.hold_goal(msg)
            return
        passage = link.book.link.passage("up")
        if not passage.lost:
            self._arrive_later("goal", link, msg, passage.delay_s)

    def submit(self, link: ArmLink, msg: ArmGoalMsg) -> None:
        goal = goal_from_message(msg)
        # refused before reaching the tracker: stamped here (the tracker stamps its own)
        if isinstance(goal, GoalResult):
            self.sim.outputs.results(link.name, [dataclasses.replace(goal, time_s=self.sim.world.sim_time_s)])
        else:
            outside = goal.goal_id in self.outside_goals
            self.outside_goals.discard(goal.goal_id)
            self.sim.outputs.results(link.name, self.sim.tracked.submit(link.name, goal, outside=outside))

    def _on_step(self, key: str, payload: bytes) -> None:
        msg = self.sim.bus.step.decode(key, payload)
        if msg is None or (link := self._link_for(key, msg.arm)) is None:
            return
        self.sim.stats.messages_in["step"] += 1
        problem = request_problem(msg, self.sim.world.arms[link.name].spec.arm_dof) or (
            "" if math.isfinite(msg.progress) else "an answer with a non-finite progress"
        )
        if problem:
            self.sim.drops.drop(key, problem)
            return
        flight = link.book.answer(msg.tick, msg)
        if flight is None:  # an answer to a state already answered, overtaken or never delivered
            self.sim.drops.drop(key, "an answer to no state that awaits one (repeated, late or never sent)")
            return
        self.sim.stats.round_trip((time.monotonic() - flight.delivered_wall_s) * 1e3)
        if self.sim.deferred:
            if flight.up_lost:
                link.answer_lost(msg.goal_ids)
            return
        passage = link.book.link.passage("up")
        if not passage.lost:
            self._arrive_later("step", link, flight, passage.delay_s)
