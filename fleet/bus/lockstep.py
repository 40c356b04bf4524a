"""Lockstep at the bus level: each arm's link (its states in flight, their answers and the goals those name) and the
barrier that waits for them. No physics here: the sim server drives it, and a test can drive it with plain messages.

An answer to a state, and every goal it names, take effect together at the arm's due tick, so a run repeats exactly;
a goal no answer names (a user's own trajectory client, a lost controller) goes with the next answers due."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

from fleet.bus.flights import BookState, FlightBook
from fleet.bus.messages import ArmGoalMsg, ArmState, ControllerStep
from robots.saved_state import SavedState

REPUBLISH_S = 0.05  # wall seconds before a state still unanswered is sent again (a late joiner, a lost sample)


class ArmLinkState(SavedState, frozen=True):
    """What an `ArmLink` saves (its name and its book's faults are the link's own)."""

    period_ticks: int
    book: BookState[ArmState, ControllerStep]
    last_step: ControllerStep | None
    next_tick: int
    goals: list[ArmGoalMsg]
    discard_goals: set[int]
    lost: bool
    watchdog_held: bool


@dataclass
class ArmLink:
    """The server's view of one arm's controller: its states in flight and their answers, when its next state is
    sampled, whether it is alive."""

    name: str
    period_ticks: int
    book: FlightBook
    last_step: ControllerStep | None = None
    next_tick: int = 0  # the tick its next state is sampled
    goals: list[ArmGoalMsg] = field(default_factory=list)  # goals in and not applied yet (lockstep), in arrival order
    discard_goals: set[int] = field(default_factory=set)  # ids named by answers lost on the way back: never applied
    lost: bool = False
    watchdog_held: bool = False

    def state(self) -> ArmLinkState:
        return ArmLinkState(
            period_ticks=self.period_ticks,
            book=self.book.state(),
            last_step=self.last_step,
            next_tick=self.next_tick,
            goals=list(self.goals),
            discard_goals=set(self.discard_goals),
            lost=self.lost,
            watchdog_held=self.watchdog_held,
        )

    def restore(self, state: ArmLinkState) -> None:
        self.period_ticks, self.last_step, self.next_tick = state.period_ticks, state.last_step, state.next_tick
        self.book.restore(state.book)
        self.goals, self.discard_goals = list(state.goals), set(state.discard_goals)
        self.lost, self.watchdog_held = state.lost, state.watchdog_held

    def named_goals(self) -> set[int]:
        """Goal ids named by answers in and not applied yet."""
        return {g for f in self.book.flights.values() if f.answer is not None for g in f.answer.goal_ids}

    def ready(self) -> bool:
        """Every state delivered has its answer, and every goal those answers name is in (lockstep)."""
        if self.book.awaiting() is not None:
            return False
        arrived = {g.goal_id for g in self.goals}
        return self.named_goals() <= arrived

    def hold_goal(self, goal: ArmGoalMsg) -> None:
        """A goal in: kept until the answer naming it (or the arm's next due tick) applies it; one whose answer was
        lost on the way back is lost with it."""
        if goal.goal_id in self.discard_goals:
            self.discard_goals.discard(goal.goal_id)
        else:
            self.goals.append(goal)

    def answer_lost(self, goal_ids: tuple[int, ...]) -> None:
        """An answer lost on the way back: it and the goals it names never reach the tracker (those still to come,
        and late copies of those already here, are dropped when they arrive)."""
        self.discard_goals.update(goal_ids)
        self.goals = [g for g in self.goals if g.goal_id not in self.discard_goals]
        self.discard_goals -= {g.goal_id for g in self.goals}

    def take_due(self, tick: int) -> tuple[list[tuple[list[ArmGoalMsg], ControllerStep]], list[ArmGoalMsg]]:
        """What takes effect at `tick`: each due answer with the goals it names (in order), then the goals that no
        answer still held names."""
        batches = []
        for flight in self.book.due_answers(tick):
            named = set(flight.answer.goal_ids)
            batches.append(([g for g in self.goals if g.goal_id in named], flight.answer))
            self.goals = [g for g in self.goals if g.goal_id not in named]
        held = self.named_goals()
        unnamed = [g for g in self.goals if g.goal_id not in held]
        self.goals = [g for g in self.goals if g.goal_id in held]
        return batches, unnamed


def unanswered(links: list[ArmLink], coord_book: FlightBook | None) -> tuple[list[ArmLink], bool]:
    """The live links still owed an answer (or a goal an answer names), and whether the coordinator still owes one
    (`coord_book` None: not asked)."""
    waiting = [link for link in links if not link.lost and not link.ready()]
    return waiting, coord_book is not None and coord_book.awaiting() is not None


@dataclass
class Barrier:
    """Lockstep's wait at a tick: until every live controller due has answered each state delivered to it (with the
    goals it names) and the coordinator each frame, or a timeout passed. States and frames still unanswered are
    sent again every `REPUBLISH_S` (a process that joined late, a lost sample)."""

    lockstep_timeout_s: float
    first_command_timeout_s: float
    coordinator_timeout_s: float

    def wait(
        self,
        links: list[ArmLink],
        coord_book: FlightBook | None,
        *,
        first: bool,
        take_inputs: Callable[[], None],
        pause: Callable[[float], None],
        lose: Callable[[ArmLink], None],
        republish: Callable[[ArmLink | None, bytes], None],
        should_stop: Callable[[], bool] = lambda: False,
    ) -> str:
        """Wait; `coord_book` None: not for the coordinator. Returns "in" (everyone answered, or the silent were
        lost), "coordinator_lost" (its timeout passed) or "stopped"."""
        started = time.monotonic()
        deadline = started + (self.first_command_timeout_s if first else self.lockstep_timeout_s)
        republish_at = started + REPUBLISH_S
        while True:
            take_inputs()
            waiting, coord_waiting = unanswered(links, coord_book)
            if not waiting and not coord_waiting:
                return "in"
            if should_stop():
                return "stopped"
            now = time.monotonic()
            if now > deadline and waiting:
                for link in waiting:
                    lose(link)
                continue
            if coord_waiting and now > max(deadline, started + self.coordinator_timeout_s):
                return "coordinator_lost"
            if time.monotonic() > republish_at:
                for link in waiting:
                    if (flight := link.book.awaiting()) is not None:
                        republish(link, flight.payload)
                if coord_waiting:
                    republish(None, coord_book.awaiting().payload)
                republish_at = time.monotonic() + REPUBLISH_S
            pause(0.01)
