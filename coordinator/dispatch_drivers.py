"""Arms an outside client drives (a ROS front end on the arm's `drive` key): while taken, an arm gets no task; the
tasks it had go back to the pool (one not started) or end (one under way: its part, if in the claw, with it), and
its controller is told to drop them. Let go, it is the allocator's again. One concern of `Dispatcher`, kept apart."""

from __future__ import annotations

from coordinator.orders import CancelOrder
from coordinator.tasks import TaskState


class OutsideDrivers:
    """Taking and letting go of arms, mixed into `Dispatcher`."""

    def arm_taken(self, arm: str) -> None:
        """An outside client took `arm`: nothing is given to it until `arm_let_go`."""
        if arm in self.taken:
            return
        self.taken.add(arm)
        self.lost[arm] = self.sim_time_s  # out of the allocation, as a lost arm is (its controller is alive)
        self.requests.pop(arm, None)
        self.guard.release(arm)
        for task in [t for t in self.ledger.tasks.values() if t.arm == arm]:
            if task.state == TaskState.ASSIGNED:
                self.ledger.requeue(task.task_id, f"{arm} was taken by an outside driver")
                self.cancels.append(CancelOrder(arm, task.part_id))
            elif task.state == TaskState.ACTIVE:
                self.cancels.append(CancelOrder(arm, task.part_id))
        self.ledger.arm_lost(arm, self.sim_time_s)  # what was under way ends with it
        self.losses.append({"arm": arm, "event": "taken", "sim_time_s": round(self.sim_time_s, 3)})

    def arm_let_go(self, arm: str) -> None:
        """The outside client let go of `arm`: the allocator may give it tasks again."""
        if arm not in self.taken:
            return
        self.taken.discard(arm)
        self.lost.pop(arm, None)
        self.losses.append({"arm": arm, "event": "let go", "sim_time_s": round(self.sim_time_s, 3)})

    def take_cancels(self) -> list[CancelOrder]:
        out, self.cancels = self.cancels, []
        return out
