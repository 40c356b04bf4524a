"""Arms an outside client drives (a ROS front end on the arm's `drive` key): while taken, an arm gets no task; the
tasks it had go back to the pool (one not started) or end (one under way: its part, if in the claw, with it), and
its controller is told to drop them. Let go, it is the allocator's again."""

from __future__ import annotations

from coordinator.dispatch_book import ArmBook, DispatchClock
from coordinator.guard import CollisionGuard
from coordinator.ledger import Ledger
from coordinator.orders import CancelOrder
from coordinator.tasks import TaskState


class OutsideDrivers:
    """Taking and letting go of arms in the dispatcher's `arms`, `ledger` and `guard`; it keeps the orders to drop
    tasks until the next decision takes them (`take_cancels`)."""

    def __init__(self, arms: ArmBook, clock: DispatchClock, ledger: Ledger, guard: CollisionGuard) -> None:
        self.arms, self.clock, self.ledger, self.guard = arms, clock, ledger, guard
        self.cancels: list[CancelOrder] = []  # orders to drop tasks, out with the next decision

    def arm_taken(self, arm: str) -> None:
        """An outside client took `arm`: nothing is given to it until `arm_let_go`."""
        arms, now_s = self.arms, self.clock.sim_time_s
        if arm in arms.taken:
            return
        arms.taken.add(arm)
        arms.lost[arm] = now_s  # out of the allocation, as a lost arm is (its controller is alive)
        arms.requests.pop(arm, None)
        self.guard.release(arm)
        for task in [t for t in self.ledger.tasks.values() if t.arm == arm]:
            if task.state == TaskState.ASSIGNED:
                self.ledger.requeue(task.task_id, f"{arm} was taken by an outside driver")
                self.cancels.append(CancelOrder(arm, task.part_id))
            elif task.state == TaskState.ACTIVE:
                self.cancels.append(CancelOrder(arm, task.part_id))
        self.ledger.arm_lost(arm, now_s)  # what was under way ends with it
        arms.losses.append({"arm": arm, "event": "taken", "sim_time_s": round(now_s, 3)})

    def arm_let_go(self, arm: str) -> None:
        """The outside client let go of `arm`: the allocator may give it tasks again."""
        arms = self.arms
        if arm not in arms.taken:
            return
        arms.taken.discard(arm)
        arms.lost.pop(arm, None)
        arms.losses.append({"arm": arm, "event": "let go", "sim_time_s": round(self.clock.sim_time_s, 3)})

    def take_cancels(self) -> list[CancelOrder]:
        out, self.cancels = self.cancels, []
        return out
