"""The ledger's records: every part and task of a run, the stacks at assembling stations, and which task of each
part is open. The ledger and its components (`StationTurns`, `Buffering`) are each handed this one object; it is
all the ledger saves in a snapshot but whether fixtures are pipelined."""

from __future__ import annotations

from coordinator.tasks import OPEN_STATES, PartRecord, Task, TaskState
from scenes.schema import Scene


class LedgerRecords:
    """Parts and tasks by id, with the queries every part of the ledger asks of them; all times are sim seconds."""

    def __init__(self, scene: Scene, first_task_id: int = 1) -> None:
        self.parts: dict[int, PartRecord] = {}
        self.tasks: dict[int, Task] = {}
        self.stacks: dict[str, list[int]] = {s.name: [] for s in scene.stations if s.assembles}
        self.next_task_id = first_task_id  # a respawned coordinator starts past its predecessors' ids
        self.open_by_part: dict[int, int] = {}
        self.finished_at: dict[int, float] = {}  # task id -> when its arm said the skill was done

    def open_task(self, part_id: int) -> Task | None:
        """The part's task not finished, if it has one."""
        task_id = self.open_by_part.get(part_id)
        return self.tasks[task_id] if task_id is not None else None

    def open_tasks(self) -> list[Task]:
        """The tasks not finished (pending, or given to an arm), without walking every task of the run."""
        return [self.tasks[task_id] for task_id in self.open_by_part.values()]

    def close(self, task: Task, state: TaskState, reason: str, code: str = "") -> None:
        """A task finished (done or failed, with the skill's failure `code` if it gave one): it stays on record, no
        longer open."""
        task.state, task.reason, task.failure_code = state, reason, code
        self.open_by_part.pop(task.part_id, None)

    def drop(self, task: Task) -> None:
        """Forget a pending task no arm was given (what it offered is gone); its part gets a task again when due."""
        del self.tasks[task.task_id]
        self.open_by_part.pop(task.part_id, None)

    def leave_stack(self, part: PartRecord) -> None:
        """The part is no longer in the stack where it lay (an assembly's bottom leaving takes the whole stack)."""
        stack = self.stacks.get(part.location)
        if stack and part.part_id in stack:
            if stack[0] == part.part_id:
                stack.clear()  # the assembly moved on (or fell) as one
            else:
                stack.remove(part.part_id)

    def inbound(self, station: str, states: tuple[TaskState, ...] = OPEN_STATES) -> list[Task]:
        """Tasks bringing a part to `station`."""
        return [t for t in self.open_tasks() if t.target == station and t.state in states]
