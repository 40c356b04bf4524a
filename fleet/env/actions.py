"""The env's continuous actions applied: each robot model's translator turns its agents' actions into drive targets
(in one pass per model, or through the arms' own processes when distributed), and the rewards of a step's task."""

from __future__ import annotations

import numpy as np

from coordinator.tasks import TaskState
from fleet.env.limits import EFFORT_WEIGHT
from fleet.env.scenarios import SUCCESS_BONUS
from fleet.sim.world import World
from robots.policy_actions import ActionTranslator


class JointActions:
    """The continuous action modes' side of an env cell: the translators by robot model, the arms' claw openings as
    last commanded. Given the world it drives and, when distributed, the actuators that translate remotely."""

    def __init__(self, world: World, agents: list[str], placements: dict, action_mode: str, actuator=None) -> None:
        self.world, self.action_mode, self.actuator = world, action_mode, actuator
        self.arms_of_model: dict[str, list[str]] = {}  # the agents of each robot model, in agent order
        for a in agents:
            self.arms_of_model.setdefault(world.arms[a].spec.uid, []).append(a)
        self.translators = {  # by model: all its arms' actions in one pass
            uid: ActionTranslator(world.arms[arms[0]].spec, [placements[a] for a in arms], action_mode)
            for uid, arms in self.arms_of_model.items()
        }
        self._still = {a: np.zeros(world.arms[a].spec.arm_dof) for a in agents}  # every action's velocity target
        self.commanded_opening = {a: 1.0 for a in agents}

    def reset(self, start_q: dict[str, np.ndarray]) -> None:
        """Each arm's targets where it stands, its claw open."""
        for uid, translator in self.translators.items():
            translator.reset(np.array([start_q[a] for a in self.arms_of_model[uid]]))
        self.commanded_opening = dict.fromkeys(self.commanded_opening, 1.0)

    def translator(self, agent: str) -> ActionTranslator:
        return self.translators[self.world.arms[agent].spec.uid]

    def joint_targets(self, agent: str) -> np.ndarray:
        """The arm joint targets an agent's actions have reached."""
        uid = self.world.arms[agent].spec.uid
        return self.translators[uid].q_target[self.arms_of_model[uid].index(agent)]

    def apply(self, actions: dict) -> tuple[dict[str, bool], dict[str, float]]:
        """Apply this step's actions; returns which arms pushed a joint target against its limit, and each arm's
        effort penalty."""
        rows = {
            uid: self._action_rows(self.arms_of_model[uid], actions, t.action_size)
            for uid, t in self.translators.items()
        }
        remote = None
        if self.actuator is not None:
            remote = self.actuator.translate(
                {a: r for uid, r_all in rows.items() for a, r in zip(self.arms_of_model[uid], r_all)}
            )
        hits, effort = {}, {}
        for uid, translator in self.translators.items():
            arms, acted = self.arms_of_model[uid], rows[uid]
            if remote is None:
                q, opening = translator.apply(acted)
            else:
                q, opening = np.array([remote[a].q for a in arms]), np.array([remote[a].gripper_opening for a in arms])
            limits, openings = translator.at_limit(q).tolist(), opening.tolist()
            efforts = (EFFORT_WEIGHT * np.einsum("ij,ij->i", acted, acted)).tolist()
            for i, a in enumerate(arms):
                arm = self.world.arms[a]
                arm.set_targets(q[i], self._still[a], arm.spec.gripper_targets(openings[i]))
                self.commanded_opening[a] = openings[i]
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


def choice_rewards(chooser, gained: float, agents: list[str]) -> tuple[dict[str, float], dict[str, bool]]:
    """The allocate mode's rewards: each arm's own tasks done (+1) or failed (-1) since the last step, plus a share of
    the line's net gain; and whether each finished one."""
    rewards, successes = {}, {}
    for a in agents:
        outcomes, chooser.outcomes[a] = chooser.outcomes[a], []
        own = sum(1.0 if o == TaskState.DONE else -1.0 for o in outcomes)
        rewards[a] = own + SUCCESS_BONUS * gained
        successes[a] = TaskState.DONE in outcomes
    return rewards, successes
