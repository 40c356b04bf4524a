"""Lockstep at the bus level, without physics: an arm's answers and the goals they name take effect together at its
due tick, a lost answer takes its goals with it, and the barrier waits for the silent until they answer or are lost."""

import time

from fleet.bus.faults import FaultyLink
from fleet.bus.flights import FlightBook
from fleet.bus.lockstep import ArmLink, Barrier
from fleet.bus.messages import ControllerStep, GripperGoalMsg
from scenes.schema import LinkFaults

HZ = 100.0
PERIOD = 5


def link(loss: float = 0.0) -> ArmLink:
    return ArmLink("arm_0", PERIOD, FlightBook(FaultyLink("arm_0", LinkFaults(loss=loss), seed=1, index=0), HZ))


def goal(goal_id: int) -> GripperGoalMsg:
    return GripperGoalMsg("arm_0", goal_id, 1.0)


def deliver(arm: ArmLink, tick: int) -> None:
    arm.book.send(tick, f"state {tick}", PERIOD, 0.0, lockstep=True)
    assert arm.book.deliver(tick, 0.0, lockstep=True) is not None


def test_an_answer_and_the_goals_it_names_take_effect_together_at_the_due_tick():
    arm = link()
    deliver(arm, 0)
    arm.hold_goal(goal(7))
    assert not arm.ready(), "the state of tick 0 has no answer yet"
    arm.book.answer(0, ControllerStep("arm_0", 0, PERIOD, (7, 8)))
    assert not arm.ready(), "goal 8 is named but not in"
    arm.hold_goal(goal(8))
    arm.hold_goal(goal(99))  # a user's own client: named by no answer
    assert arm.ready()
    assert arm.book.due_answers(PERIOD - 1) == [], "no answer takes effect before its period ends"
    batches, unnamed = arm.take_due(PERIOD)
    ((goals, answer),) = batches
    assert [g.goal_id for g in goals] == [7, 8] and answer.tick == 0
    assert [g.goal_id for g in unnamed] == [99] and arm.goals == []


def test_an_answer_lost_on_the_way_back_takes_its_goals_with_it_even_those_still_to_come_and_late_copies():
    arm = link()
    deliver(arm, 0)
    arm.hold_goal(goal(1))
    arm.answer_lost((1, 2))
    arm.hold_goal(goal(2))  # arrives after its answer was lost
    arm.hold_goal(goal(3))
    arm.hold_goal(goal(1))  # a copy of one it named, late: never applied either
    assert [g.goal_id for g in arm.goals] == [3]


def barrier() -> Barrier:
    return Barrier(lockstep_timeout_s=0.2, first_command_timeout_s=0.2, coordinator_timeout_s=0.2)


def test_the_barrier_waits_for_an_answer_that_comes_and_resends_the_state_meanwhile():
    arm = link()
    deliver(arm, 0)
    arm.book.awaiting().payload = b"state 0"
    sent, polls = [], []

    def take_inputs() -> None:
        polls.append(1)
        if len(polls) == 8:  # the controller answers after a while
            arm.book.answer(0, ControllerStep("arm_0", 0, PERIOD))

    lost = []
    outcome = barrier().wait(
        [arm],
        None,
        first=False,
        take_inputs=take_inputs,
        pause=time.sleep,
        lose=lost.append,
        republish=lambda a, payload: sent.append((a.name, payload)),
    )
    assert outcome == "in" and lost == [] and arm.ready()
    assert sent and all(s == ("arm_0", b"state 0") for s in sent), "a state still unanswered is sent again"


def test_the_barrier_loses_a_silent_controller_after_the_timeout_and_a_silent_coordinator_too():
    arm, coord = link(), FlightBook(FaultyLink("coordinator", LinkFaults(), seed=1, index=1), HZ)
    deliver(arm, 0)
    lost = []

    def lose(a: ArmLink) -> None:
        lost.append(a.name)
        a.lost = True

    outcome = barrier().wait(
        [arm], None, first=False, take_inputs=lambda: None, pause=lambda s: None, lose=lose, republish=lambda a, p: None
    )
    assert outcome == "in" and lost == ["arm_0"]
    coord.send(0, "frame 0", 1, 0.0, lockstep=True)
    coord.deliver(0, 0.0, lockstep=True)
    outcome = barrier().wait(
        [], coord, first=False, take_inputs=lambda: None, pause=lambda s: None, lose=lose, republish=lambda a, p: None
    )
    assert outcome == "coordinator_lost"
