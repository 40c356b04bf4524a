"""The coordinator's messages: a decision's orders as bus messages, and its running progress."""

from __future__ import annotations

import math

from coordinator.dispatcher import Dispatcher
from coordinator.orders import AssignOrder, CancelOrder, GrantOrder
from fleet.bus.messages import Assignment, MotionGrant, Progress


def order_message(
    order: AssignOrder | CancelOrder | GrantOrder, seq: int, holder: int, decision_tick: int = -1
) -> Assignment | MotionGrant:
    """One order as the arm's `assign` key carries it, numbered `seq` in that arm's count, from the coordinator
    in its `holder`th start, given by its decision at `decision_tick`."""
    if isinstance(order, GrantOrder):
        return MotionGrant(
            order.arm,
            seq,
            order.request_seq,
            order.decision,
            order.conflict_arm,
            order.min_separation_m if math.isfinite(order.min_separation_m) else -1.0,
            order.start_s if order.start_s is not None else -1.0,
            holder,
            decision_tick,
        )
    if isinstance(order, CancelOrder):
        return Assignment(
            order.arm, seq, None, order.part_id, 0.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), holder, decision_tick
        )
    assert isinstance(order, AssignOrder)
    return Assignment(
        order.arm,
        seq,
        order.task_id,
        order.part_id,
        order.surface_z_m,
        order.place_xyz,
        order.surface_velocity,
        holder,
        decision_tick,
    )


def progress_message(d: Dispatcher) -> Progress:
    """The line's running figures, as the monitor and the launcher's progress bar show them."""
    t = d.ledger.totals()
    return Progress(
        d.sim_time_s,
        t["parts_spawned"],
        t["parts_completed"],
        t["parts_missed"],
        d.views.busy_arms(),
        t.get("parts_failed", 0),
        d.guard.denied,
        d.grants.min_separation_m if math.isfinite(d.grants.min_separation_m) else -1.0,
    )
