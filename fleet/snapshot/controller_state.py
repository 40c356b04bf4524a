"""What an arm controller saves in a run's snapshot: its skill, its orders, the parts it sees and its counts; not its
bus handles, nor what it was started with (its arm, scene and rate), which the controller it is put back into has."""

from __future__ import annotations

from fleet.bus.message_checks import IncarnationsState
from fleet.bus.messages import ArmOrder, Assignment, MotionGrant, PartsState
from fleet.snapshot.process_state import StateError
from robots.saved_state import SavedState, SavedStateError, unpack_version
from robots.skills.interface import PartObservation
from robots.skills.skill_state import SkillState

VERSION = 1  # bumped when a field keeps its name and type but changes its meaning


class OrdersState(SavedState, frozen=True):
    """What `fleet.nodes.arm_orders.ControllerOrders` saves."""

    holders: IncarnationsState
    assign_seq: int | None
    received: list[ArmOrder]
    pending: Assignment | None
    grants: list[MotionGrant]
    missed: int


class FeedState(SavedState, frozen=True):
    """What a `fleet.nodes.sim_feed.SimFeed` saves."""

    newest_tick: int | None  # the newest tick believed from the sim
    parts: dict[int, PartObservation]  # the parts as of `parts_tick`
    parts_tick: int
    parts_seen: list[PartsState]  # the newest parts messages, oldest first
    parts_late: int


class ControllerState(SavedState, frozen=True):
    """An `ArmController`'s state (`fleet.nodes.arm_controller.controller_state`, `restore_controller`)."""

    version: int
    incarnation: int
    skill: SkillState
    orders: OrdersState
    feed: FeedState
    delays: list[int]  # ticks each recent state spent on the bus
    answered: list[int]  # ticks answered lately
    task_id: int | None
    sim_time_s: float
    seq: int
    decisions: int
    goals_sent: int
    busy_s: float
    drops: list[tuple[str, str, int]]  # messages dropped: key, reason, how many


def read_controller_state(data: bytes, arm: str) -> ControllerState:
    """A state from `controller_state`; another version, or bytes that are not one, is a one-line `StateError`."""
    try:
        return unpack_version(data, ControllerState, VERSION)
    except SavedStateError as exc:
        raise StateError(f"cannot read back the state of {arm}: {exc}") from None
