"""The records the coordinator keeps: parts on the line and the pick-and-place tasks made from them."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

CONVEYOR = "conveyor"


class TaskState(str, Enum):
    PENDING = "pending"  # ready to be given to an arm
    ASSIGNED = "assigned"  # sent to an arm, not yet seen running
    ACTIVE = "active"  # the arm's skill runs it
    DONE = "done"  # the part came to rest at the target
    FAILED = "failed"  # the skill failed or the arm was lost; the part may get a new task


TAKEN_STATES = (TaskState.ASSIGNED, TaskState.ACTIVE)  # given to an arm, not finished
OPEN_STATES = (TaskState.PENDING, *TAKEN_STATES)


class PartFate(str, Enum):
    ON_LINE = "on_line"  # still travelling its route
    COMPLETED = "completed"  # reached its route's last station
    MISSED = "missed"  # left the line (fell, ran off the belt) before completing
    FAILED = "failed"  # gave up on it: retries exhausted, or stuck in a lost arm's claw


@dataclass
class PartRecord:
    """One part: where it is (`conveyor`, a station, or `held` by an arm) and how far along its route."""

    part_id: int
    feeder: str
    type_index: int
    height_m: float
    route: list[str]
    arrived_s: float
    location: str = CONVEYOR
    hop: int = 0
    attempts: int = 0
    fate: PartFate = PartFate.ON_LINE
    reason: str = ""
    held_from: str | None = None  # where the part was when an arm took it (and the stack it was in then)
    held_stack: tuple[int, ...] = ()
    # arms that could not grasp it as it lies (`FailureCode.UNREACHABLE`)
    refused_by: set[str] = field(default_factory=set)
    denials: int = 0  # approaches to it the guard denied (no attempt: nothing was touched)
    held_off: tuple[tuple[str, float], ...] = ()  # (arm, until_s): arms a denied approach keeps from it a while

    @property
    def next_station(self) -> str | None:
        return self.route[self.hop] if self.hop < len(self.route) else None


@dataclass
class Task:
    """Move `part_id` from `source` (conveyor or a station) to station `target`."""

    task_id: int
    part_id: int
    source: str
    target: str
    created_s: float
    state: TaskState = TaskState.PENDING
    arm: str | None = None
    assigned_s: float | None = None
    reason: str = ""
    stations: tuple[str, ...] = field(default=())
    deadline_s: float | None = None  # belt tasks: when the part rides out of every arm's reach
    done_s: float | None = None  # when the part came to rest at the target (DONE tasks)
    reassignments: int = 0
    # other stations that would do as the target (a sorted part: any bin of its colour)
    alternatives: tuple[str, ...] = ()
    refused_by: tuple[str, ...] = ()  # arms not given it: out of their reach as it lies, or held off by a denial
    failure_code: str = ""  # a failed task: the skill's `FailureCode` ("": none given, or not failed)

    @property
    def all_targets(self) -> tuple[str, ...]:
        """The target and the alternatives: every station the part may go to."""
        return (self.target, *self.alternatives)

    def retarget(self, target: str) -> None:
        """Make `target` (the target or one of the alternatives) the station this task goes to."""
        if target != self.target:
            self.go_to(target, tuple(s for s in (self.target, *self.alternatives) if s != target))

    def go_to(self, target: str, alternatives: tuple[str, ...] = ()) -> None:
        """Send this task to `target`, with `alternatives` the other stations that would do as well."""
        self.target, self.alternatives = target, alternatives
        self.stations = tuple(s for s in (self.source, self.target) if s != CONVEYOR)

    def __post_init__(self) -> None:
        self.go_to(self.target, self.alternatives)
