"""A trained policy as the line's allocator (`--allocator policy:FILE`): every free arm's choices are built as the
env's allocate mode builds them (`coordinator.choice_slots`), the policy file scores each arm's actions, and each
arm takes its best valid one, arms in id order, the first arm to a part keeping it, as the env decides.
"""

from __future__ import annotations

import numpy as np

from coordinator.allocation import ArmView, Eligibility, PartView, TimeCost
from coordinator.choice_slots import ArmChoices, arm_choices, choice_features, choice_mask, chosen_pairs, masked_choice
from coordinator.deadlines import layout_belt_reach, time_left_s
from coordinator.policy_file import ChoicePolicy
from coordinator.tasks import Task
from scenes.schema import Scene

PREFIX = "policy:"  # `--allocator policy:FILE`


class PolicyAllocator:
    """Allocates with a policy file's choices; deterministic (a forward pass, then the highest valid logit)."""

    def __init__(self, scene: Scene, policy: ChoicePolicy) -> None:
        self.scene, self.policy = scene, policy
        self.name = f"policy:{policy.path.name}"

    def allocate(
        self, tasks: list[Task], arms: list[ArmView], parts: dict[int, PartView], busy_stations: set[str]
    ) -> list[tuple[int, str]]:
        choices, features = self.observe(tasks, arms, parts, busy_stations)
        if not features:
            return []
        logits = self.policy.logits(np.stack(list(features.values())))
        actions = {a: masked_choice(row, choice_mask(choices[a])) for a, row in zip(features, logits)}
        return chosen_pairs(actions, choices)

    def observe(
        self, tasks: list[Task], arms: list[ArmView], parts: dict[int, PartView], busy_stations: set[str]
    ) -> tuple[dict[str, ArmChoices], dict[str, np.ndarray]]:
        """Every arm's choices, and the choice features of each arm that has any (what the env's `observe="choices"`
        observation is for that arm in the same state)."""
        if not tasks or not any(a.free for a in arms):
            return {}, {}
        choices = arm_choices(arms, tasks, parts, busy_stations, TimeCost(Eligibility(self.scene, arms)))
        conveyor, reach = self.scene.conveyor, layout_belt_reach(self.scene, arms)
        left = lambda task: time_left_s(conveyor, reach.for_station(task.target), parts[task.part_id])
        features = {
            a.name: choice_features(self.scene, choices[a.name], parts, left) for a in arms if choices[a.name].options
        }
        return choices, features
