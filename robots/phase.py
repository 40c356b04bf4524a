"""The phases of the pick-and-place skill, and the groups of them that the coordinator, the sim, the env, the
recorder and the monitor reason about: the one place a phase is named (bus messages carry its value)."""

from __future__ import annotations

from enum import Enum


class Phase(str, Enum):
    """Where an arm's skill is in its job; a `str` so that a phase read off the bus compares equal to it."""

    IDLE = "idle"
    APPROACH = "approach"
    DESCEND = "descend"
    CLOSE = "close"
    LIFT = "lift"
    STANDBY = "standby"  # a part in the claw, beside the place, until the coordinator says the place is ready
    TRANSFER = "transfer"
    LOWER = "lower"
    RELEASE = "release"
    RETREAT = "retreat"
    HOME = "home"
    DONE = "done"
    FAILED = "failed"

    def __str__(self) -> str:
        return self.value

    def __format__(self, spec: str) -> str:
        return format(self.value, spec)


# the order of a job's phases (standby, when it happens, lies between lift and transfer)
ORDER = (
    Phase.APPROACH,
    Phase.DESCEND,
    Phase.CLOSE,
    Phase.LIFT,
    Phase.TRANSFER,
    Phase.LOWER,
    Phase.RELEASE,
    Phase.RETREAT,
    Phase.HOME,
)
IDLE_PHASES = (Phase.IDLE, Phase.DONE, Phase.FAILED)  # an arm that is not working on a task
AVAILABLE_PHASES = (*IDLE_PHASES, Phase.HOME)  # an arm that may take a task: its way home is given up for it
SEGMENT_PHASES = (Phase.APPROACH, Phase.STANDBY, Phase.TRANSFER, Phase.HOME)  # free moves: the ones asked a grant for
GRASP_PHASES = (Phase.DESCEND, Phase.CLOSE, Phase.LIFT)  # the grasp after an approach: moves asked no grant
PLACE_PHASES = (Phase.LOWER, Phase.RELEASE, Phase.RETREAT)  # the place after a transfer: moves asked no grant
LOCAL_PHASES = (*GRASP_PHASES, *PLACE_PHASES)
HOLDING_PHASES = (Phase.LIFT, Phase.STANDBY, Phase.TRANSFER, Phase.LOWER, Phase.RELEASE)  # a part in the claw
