"""Why a skill ended its task failed: a code that the coordinator acts on, and the sentence that people read.

The coordinator decides by the code (a part an arm cannot grasp as it lies is not given to that arm again); the
text only explains. A controller sends both (`ControllerStep.failure_code` and `.failure`)."""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class FailureCode(str, Enum):
    """What went wrong, as the coordinator and the summaries tell failures apart."""

    UNREACHABLE = "unreachable"  # the part cannot be grasped from above as it lies: its pose will not change
    MOTION_DENIED = "motion_denied"  # the coordinator denied the approach
    GOAL_LOST = "goal_lost"  # a trajectory goal never reached the tracker, after resends
    GOAL_FAILED = "goal_failed"  # the tracker aborted or rejected a goal (path tolerance, e-stop, watchdog)
    PART_VANISHED = "part_vanished"  # the part left the line before the grasp
    GRASP_MISSED = "grasp_missed"  # the claw closed on nothing
    PLACE_UNREACHABLE = "place_unreachable"  # the place position cannot be reached
    REJECTED = "rejected"  # refused before it started (an unknown part)
    CANCELLED = "cancelled"  # stopped from outside (a new order, the line stopping)

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class Failure:
    """A failed task's code and its sentence."""

    code: FailureCode
    reason: str
