"""An arm's choices among the line's pending tasks, as a learned allocator sees them: at most `SLOTS` tasks it can
serve now (oldest first, with estimated seconds), how soon a belt part it cannot serve yet rides into its reach, the
feature vector of both, and which pairs a set of choices gives (arms in id order, the first arm to a part keeps it).

The env's `allocate` mode (its observations and actions) and the coordinator's `policy:FILE` allocator both build
choices here, so a policy trained in the env sees in the running line exactly what it saw in training.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from coordinator.allocation import (
    LOOKAHEAD_S,
    ArmView,
    PartView,
    TimeCost,
    open_candidates,
    served_after_wait,
)
from coordinator.tasks import Task
from scenes.schema import Scene

SLOTS = 4  # the first SLOTS tasks an arm can serve, oldest first, are its choices
# valid, pick point xyz, place point xyz, estimated seconds / 10, on the belt (0/1), slack seconds / 10
SLOT_FEATURES = 10
CHOICE_FEATURES = 1 + SLOTS * SLOT_FEATURES  # how soon a part comes / LOOKAHEAD_S, then the slots
WAIT = 0  # action 0: take nothing new now; action k: the k-th choice
FEATURE_LIMIT = 100.0  # features are clipped here (they never come near it on a cell's scale)


@dataclass(frozen=True)
class ArmChoices:
    """What one arm may take now: (task, estimated seconds) pairs, oldest first, at most `SLOTS`; and how soon (s) a
    belt part it cannot serve yet rides into its reach (`LOOKAHEAD_S` when none does)."""

    options: tuple[tuple[Task, float], ...] = ()
    coming_s: float = LOOKAHEAD_S


def arm_choices(
    arms: list[ArmView], tasks: list[Task], parts: dict[int, PartView], busy_stations: set[str], cost: TimeCost
) -> dict[str, ArmChoices]:
    """Each arm's choices: a free arm's open tasks (part seen, stations not in `busy_stations`) it can serve, and the
    soonest wait after which one it cannot serve yet comes into reach; a busy arm has none."""
    open_tasks = open_candidates(tasks, parts, busy_stations)
    out = {}
    for arm in arms:
        if not arm.free:
            out[arm.name] = ArmChoices()
            continue
        scored = [(t, cost(arm, t, parts[t.part_id])) for t in open_tasks]
        options = tuple((t, s) for t, s in scored if math.isfinite(s))[:SLOTS]
        waits = [served_after_wait(arm, t, parts[t.part_id], cost) for t, s in scored if not math.isfinite(s)]
        out[arm.name] = ArmChoices(options, min([w[0] for w in waits if w is not None], default=LOOKAHEAD_S))
    return out


def choice_features(
    scene: Scene, choices: ArmChoices, parts: dict[int, PartView], time_left_s: Callable[[Task], float | None]
) -> np.ndarray:
    """One arm's choices as a vector (float32, `CHOICE_FEATURES` long): how soon a belt part rides into its reach /
    `LOOKAHEAD_S`, then per slot: valid, pick point, place point (the station's centre at its surface), estimated
    seconds / 10, on the belt (0/1) and the slack (seconds left to the part's deadline after the task / 10; 0 for a
    part at rest). `time_left_s(task)`: seconds until a belt task's part rides out of reach of the arms that can
    take it."""
    slots = np.zeros((SLOTS, SLOT_FEATURES))
    for i, (task, seconds) in enumerate(choices.options):
        station = scene.station(task.target)
        left = time_left_s(task) if task.deadline_s is not None else None
        slots[i] = [
            1.0,
            *parts[task.part_id].position[:3],
            station.pose.xyz[0],
            station.pose.xyz[1],
            station.surface_z_m,
            seconds / 10.0,
            float(left is not None),
            0.0 if left is None else (left - seconds) / 10.0,
        ]
    vector = np.concatenate([[choices.coming_s / LOOKAHEAD_S], slots.ravel()])
    return np.clip(vector, -FEATURE_LIMIT, FEATURE_LIMIT).astype(np.float32)


def choice_mask(choices: ArmChoices) -> np.ndarray:
    """Which actions choose something real (1): waiting always, then one per filled slot (int8, `SLOTS + 1`)."""
    mask = np.zeros(SLOTS + 1, dtype=np.int8)
    mask[: 1 + len(choices.options)] = 1
    return mask


def masked_choice(logits: np.ndarray, mask: np.ndarray) -> int:
    """The action a policy's logits pick among the valid ones (highest first, ties to the lowest: deterministic)."""
    return int(np.argmax(np.where(mask.astype(bool), np.asarray(logits, float), -np.inf)))


def chosen_pairs(actions: dict[str, int], choices: dict[str, ArmChoices]) -> list[tuple[int, str]]:
    """The (task id, arm) pairs the arms' actions choose, arms in the order given: an arm whose part or stations an
    arm before it took waits (as the env refuses it); an empty slot or `WAIT` chooses nothing."""
    taken_parts: set[int] = set()
    taken_stations: set[str] = set()
    out = []
    for arm, action in actions.items():
        options = choices[arm].options
        if action == WAIT or action > len(options):
            continue
        task = options[action - 1][0]
        if task.part_id in taken_parts or taken_stations.intersection(task.stations):
            continue
        taken_parts.add(task.part_id)
        taken_stations.update(task.stations)
        out.append((task.task_id, arm))
    return out
