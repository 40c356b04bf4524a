"""The env's actions applied: continuous actions translated into drive targets per robot model, and the allocate mode's
rewards."""

from __future__ import annotations

import numpy as np

from coordinator.tasks import TaskState
from fleet.env.limits import (
    EFFORT_WEIGHT,
)
from fleet.env.scenarios import SUCCESS_BONUS


class EnvActions:
    """Applying the agents' actions: one concern of `CellParallelEnv`, kept apart."""

    def _act(self, actions: dict) -> tuple[dict[str, bool], dict[str, float]]:
        """Apply this step's actions; returns which arms pushed a joint target against its limit, and each arm's
        effort penalty."""
        if self.chooser is not None:
            self._choice_results = self.chooser.choose(actions, self._options)
            return {}, {}
        if not self.agents:
            return {}, {}
        rows = {
            uid: self._action_rows(self._arms_of_model[uid], actions, t.action_size)
            for uid, t in self.translators.items()
        }
        remote = None
        if self.actuator is not None:
            remote = self.actuator.translate(
                {a: r for uid, r_all in rows.items() for a, r in zip(self._arms_of_model[uid], r_all)}
            )
        hits, effort = {}, {}
        for uid, translator in self.translators.items():
            arms, acted = self._arms_of_model[uid], rows[uid]
            if remote is None:
                q, opening = translator.apply(acted)
            else:
                q, opening = np.array([remote[a].q for a in arms]), np.array([remote[a].gripper_opening for a in arms])
            limits, openings = translator.at_limit(q).tolist(), opening.tolist()
            efforts = (EFFORT_WEIGHT * np.einsum("ij,ij->i", acted, acted)).tolist()
            for i, a in enumerate(arms):
                arm = self.world.arms[a]
                arm.set_targets(q[i], self._still[a], arm.spec.gripper_targets(openings[i]))
                self._commanded_opening[a] = openings[i]
                hits[a], effort[a] = limits[i], efforts[i]
        return hits, effort

    def _action_rows(self, arms: list[str], actions: dict, size: int) -> np.ndarray:
        """The actions of `arms` as rows (zeros for an arm that did not act); a wrong size is refused by name."""
        rows = np.zeros((len(arms), size))
        for i, a in enumerate(arms):
            if a in actions:
                action = np.asarray(actions[a], float).reshape(-1)
                if action.size != size:
                    raise ValueError(f"{a}: a {self.action_mode} action has {size} entries, got {action.size}")
                rows[i] = action
        return rows

    def _task_rewards(
        self, tools: dict[str, np.ndarray], targets: dict[str, np.ndarray]
    ) -> tuple[dict[str, float], dict[str, bool]]:
        if self.chooser is None:
            return self.scenario.progress(self.world, tools, targets)
        gained = self.scenario.book.net_gain()
        rewards, successes = {}, {}
        for a in self.agents:
            outcomes, self.chooser.outcomes[a] = self.chooser.outcomes[a], []
            own = sum(1.0 if o == TaskState.DONE else -1.0 for o in outcomes)
            rewards[a] = own + SUCCESS_BONUS * gained
            successes[a] = TaskState.DONE in outcomes
        return rewards, successes
