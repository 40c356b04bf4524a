"""What the coordinator's decisions save (`Dispatcher`, its `Ledger` and `CollisionGuard`): tasks, parts, grants,
what each arm does and the counts; not what is worked out from the scene (reach, the line's bound, the belt's
reach, the arms' shapes) nor caches that give the same answers afresh, which a dispatcher of the same scene has.
The allocator keeps no state across decisions (`docs/allocators.md`): a restored dispatcher's is built anew."""

from __future__ import annotations

from typing import Any

import numpy as np

from coordinator.allocation import PartView
from coordinator.claw_sweep import ClawSpan
from coordinator.dispatcher import Dispatcher
from coordinator.guard import CollisionGuard, TimedPath
from coordinator.ledger import Ledger
from coordinator.orders import CancelOrder
from coordinator.pair_measurements import PairMeasurements
from coordinator.tasks import PartRecord, Task
from robots.saved_state import SavedState


class LedgerState(SavedState, frozen=True):
    """What a `Ledger` saves."""

    pipeline: bool
    parts: dict[int, PartRecord]
    tasks: dict[int, Task]
    stacks: dict[str, list[int]]
    next_task_id: int
    open_by_part: dict[int, int]
    finished_at: dict[int, float]


class GuardState(SavedState, frozen=True):
    """What a `CollisionGuard` saves: each arm's joints and claw as last measured, the grants out, the counts."""

    joints: dict[str, np.ndarray]
    claws: dict[str, ClawSpan]
    grants: dict[str, TimedPath]
    denied: int
    waits: int
    ways_out: int
    last_check_samples: int


class DispatcherState(SavedState, frozen=True):
    """What a `Dispatcher` saves."""

    ledger: LedgerState
    guard: GuardState
    phase: dict[str, str]
    acts_at_tick: dict[str, int]
    last_stations: dict[str, tuple[str, ...]]
    last_task: dict[str, int]
    requests: dict[str, TimedPath]
    request_seq: dict[str, int]
    lost: dict[str, float]
    taken: set[str]
    cancels: list[CancelOrder]
    busy_until_s: dict[str, float]
    deadline_known: set[int]
    parts: dict[int, PartView]
    sim_time_s: float
    last_event_s: float
    last_decision_tick: int
    decisions: int
    grants_given: int
    reassigned: int
    min_separation_m: float
    closest_pair: tuple[str, str] | None
    losses: list[dict[str, Any]]  # the summary's `arm_events`
    unsettled: set[str]
    settle_by_s: float
    adopted: list[dict[str, Any]]
    held_at_station_s: dict[str, float]
    held_now: dict[str, str]
    told_standby: set[int]
    candidates: dict[int, tuple[int, str]]


def ledger_state(ledger: Ledger) -> LedgerState:
    records = ledger.records
    return LedgerState(
        pipeline=ledger.pipeline,
        parts=dict(records.parts),
        tasks=dict(records.tasks),
        stacks={name: list(stack) for name, stack in records.stacks.items()},
        next_task_id=records.next_task_id,
        open_by_part=dict(records.open_by_part),
        finished_at=dict(records.finished_at),
    )


def restore_ledger(ledger: Ledger, s: LedgerState) -> None:
    """`s` put into the ledger's records in place (its components hold them)."""
    records = ledger.records
    ledger.turns.pipeline = s.pipeline
    records.parts, records.tasks = dict(s.parts), dict(s.tasks)
    records.stacks = {name: list(stack) for name, stack in s.stacks.items()}
    records.next_task_id, records.open_by_part, records.finished_at = (
        s.next_task_id,
        dict(s.open_by_part),
        dict(s.finished_at),
    )


def guard_state(guard: CollisionGuard) -> GuardState:
    return GuardState(
        joints=dict(guard.state),
        claws=dict(guard.claw_state()),
        grants=dict(guard.grants),
        denied=guard.denied,
        waits=guard.waits,
        ways_out=guard.ways_out,
        last_check_samples=guard.last_check_samples,
    )


def restore_guard(guard: CollisionGuard, s: GuardState) -> None:
    guard.state, guard._claws, guard.grants = dict(s.joints), dict(s.claws), dict(s.grants)
    guard.denied, guard.waits, guard.ways_out = s.denied, s.waits, s.ways_out
    guard.last_check_samples = s.last_check_samples
    guard._watch_memo = PairMeasurements()  # measured again where asked: the same answers


def dispatcher_state(d: Dispatcher) -> DispatcherState:
    """What `d` saves: its ledger, guard, arm book and clock, and what its components keep."""
    arms, clock, grants = d.arms, d.clock, d.grants
    return DispatcherState(
        ledger=ledger_state(d.ledger),
        guard=guard_state(d.guard),
        phase=dict(arms.phase),  # phases as the bus says them (`robots.phase.Phase` values)
        acts_at_tick=dict(arms.acts_at_tick),
        last_stations=dict(arms.last_stations),
        last_task=dict(arms.last_task),
        requests=dict(arms.requests),
        request_seq=dict(arms.request_seq),
        lost=dict(arms.lost),
        taken=set(arms.taken),
        cancels=list(d.drivers.cancels),
        busy_until_s=dict(arms.busy_until_s),
        deadline_known=set(d.deadline_known),
        parts=dict(d.parts),
        sim_time_s=clock.sim_time_s,
        last_event_s=clock.last_event_s,
        last_decision_tick=clock.last_decision_tick,
        decisions=d.decisions,
        grants_given=grants.grants_given,
        reassigned=d.reassigned,
        min_separation_m=grants.min_separation_m,
        closest_pair=grants.closest_pair,
        losses=list(arms.losses),
        unsettled=set(arms.unsettled),
        settle_by_s=arms.settle_by_s,
        adopted=list(d.takeover.adopted),
        held_at_station_s=dict(grants.held_at_station_s),
        held_now=dict(grants.held_now),
        told_standby=set(grants.told_standby),
        candidates=dict(d._candidates),
    )


def restore_dispatcher(d: Dispatcher, s: DispatcherState) -> None:
    """Put `s` back into `d`, a dispatcher of the same scene's arms (into its components' objects, in place)."""
    restore_ledger(d.ledger, s.ledger)
    restore_guard(d.guard, s.guard)
    arms, clock, grants = d.arms, d.clock, d.grants
    arms.phase, arms.acts_at_tick, arms.last_stations = dict(s.phase), dict(s.acts_at_tick), dict(s.last_stations)
    arms.last_task, arms.requests, arms.request_seq = dict(s.last_task), dict(s.requests), dict(s.request_seq)
    arms.lost, arms.taken, arms.busy_until_s = dict(s.lost), set(s.taken), dict(s.busy_until_s)
    arms.losses, arms.unsettled, arms.settle_by_s = list(s.losses), set(s.unsettled), s.settle_by_s
    clock.sim_time_s, clock.last_event_s, clock.last_decision_tick = s.sim_time_s, s.last_event_s, s.last_decision_tick
    d.drivers.cancels, d.takeover.adopted = list(s.cancels), list(s.adopted)
    d.deadline_known, d.parts = set(s.deadline_known), dict(s.parts)
    d.decisions, d.reassigned = s.decisions, s.reassigned
    grants.grants_given, grants.min_separation_m, grants.closest_pair = (
        s.grants_given,
        s.min_separation_m,
        s.closest_pair,
    )
    grants.held_at_station_s, grants.held_now = dict(s.held_at_station_s), dict(s.held_now)
    grants.told_standby, d._candidates = set(s.told_standby), dict(s.candidates)
