"""What each agent of the env observes: spaces, action masks, joints, separations, claw poses, the observation vectors
and the env's state."""

from __future__ import annotations

from dataclasses import dataclass

import gymnasium
import numpy as np

from coordinator.choice_slots import CHOICE_FEATURES, SLOTS, ArmChoices, choice_mask
from coordinator.guard import CollisionGuard
from fleet.env.actions import JointActions
from fleet.env.camera_views import EnvCameras
from fleet.env.limits import (
    OBS_LIMIT,
    SEPARATION_CAP_M,
)
from fleet.sim.world import World


@dataclass(frozen=True)
class ObservationSettings:
    """What an env cell's agents observe, fixed when the env is made."""

    observe: str  # "cell", or "choices" (allocate mode)
    action_mode: str
    mask_in_observation: bool
    camera_obs: bool  # the cameras' images beside each agent's state


class EnvObserver:
    """The agents' observations, spaces and masks, and the env's state, read from the cell it is handed: the world
    (handed again when an episode builds a new one), the guard for separations, the scenario, the allocate mode's
    chooser or the joint actions, and the cameras."""

    def __init__(
        self,
        settings: ObservationSettings,
        agents: list[str],
        world: World,
        guard: CollisionGuard,
        scenario,
        chooser=None,
        joint_actions: JointActions | None = None,
        cameras: EnvCameras | None = None,
    ) -> None:
        self.settings, self.agents = settings, list(agents)
        self.world, self.guard, self.scenario = world, guard, scenario
        self.chooser, self.joint_actions, self.cameras = chooser, joint_actions, cameras
        self.dof = {a: world.arms[a].spec.arm_dof for a in agents}

    def observation_space(self, agent: str) -> gymnasium.spaces.Space:
        state = self._state_space(agent)
        return self.cameras.space(agent, state) if self.settings.camera_obs else state

    def _state_space(self, agent: str) -> gymnasium.spaces.Space:
        n, others = self.dof[agent], len(self.agents) - 1
        if self.settings.observe == "choices":
            size = CHOICE_FEATURES
        elif self.settings.action_mode == "allocate":
            size = n + n + 1 + 2 + 3 + 3 * others + 1 + CHOICE_FEATURES
        else:
            size = n + n + 1 + 3 + 3 + 3 * others + 1
        box = gymnasium.spaces.Box(-OBS_LIMIT, OBS_LIMIT, shape=(size,), dtype=np.float32)
        if not self.settings.mask_in_observation:
            return box
        mask = gymnasium.spaces.Box(0, 1, shape=(SLOTS + 1,), dtype=np.int8)  # PettingZoo's classic-env convention
        return gymnasium.spaces.Dict({"observation": box, "action_mask": mask})

    def action_mask(self, agent: str) -> np.ndarray:
        """Allocate mode: which actions choose something real now (1) or an empty slot (0); waiting (0) is always valid.
        A busy arm may only wait. Two arms may still pick the same task in one step: the later one is refused."""
        return choice_mask(self.chooser.arm_choices.get(agent, ArmChoices()))

    def action_space(self, agent: str) -> gymnasium.spaces.Space:
        if self.settings.action_mode == "allocate":
            return gymnasium.spaces.Discrete(SLOTS + 1)  # 0: take nothing new; k: the k-th choice
        size = self.joint_actions.translator(agent).action_size
        return gymnasium.spaces.Box(-1.0, 1.0, shape=(size,), dtype=np.float32)

    def joints(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Every arm's joint positions and velocities now (read once a step: observations and separations share
        them)."""
        return {a: (self.world.arms[a].qpos(), self.world.arms[a].qvel()) for a in self.agents}

    def separations(self, joints: dict[str, tuple[np.ndarray, np.ndarray]]) -> dict[str, float]:
        """Each arm's distance to its nearest other arm (python-fcl, the coordinator's guard)."""
        if len(self.agents) < 2:
            return {a: SEPARATION_CAP_M for a in self.agents}
        for a in self.agents:
            self.guard.set_state(a, joints[a][0][: self.dof[a]], joints[a][0][self.dof[a] :])
        return self.guard.nearest_other_m(cap_m=SEPARATION_CAP_M)

    def tools(self) -> dict[str, np.ndarray]:
        """Every arm's claw position now (world frame)."""
        return {a: np.asarray(self.world.arms[a].tool_pose_world().p, float) for a in self.agents}

    def observe(self, acting: list[str], *seen) -> dict:
        """Every acting agent's observation; with cameras, its state beside the images of the cameras it sees."""
        states = self._states(acting, *seen)
        if not self.settings.camera_obs:
            return states
        self.cameras.render()
        return {a: self.cameras.observation(a, state) for a, state in states.items()}

    def _states(
        self,
        acting: list[str],
        separation: dict[str, float] | None = None,
        tools: dict[str, np.ndarray] | None = None,
        joints: dict[str, tuple[np.ndarray, np.ndarray]] | None = None,
        targets: dict[str, np.ndarray] | None = None,
    ) -> dict[str, np.ndarray]:
        if self.settings.observe == "choices":
            return {a: self._masked(a, self.chooser.features(a)) for a in acting}
        joints = joints or self.joints()
        separation = separation or self.separations(joints)
        tools = tools or self.tools()
        out = {}
        for a in acting:
            (q, dq), n = joints[a], self.dof[a]
            others = [tools[b] for b in self.agents if b != a]
            if self.chooser is not None:
                skill = self.chooser.skills[a]
                own = [
                    q[:n],
                    dq[:n],
                    [self._opening(a)],
                    [float(self.chooser.task_of[a] is None and not skill.active), skill.progress],
                    tools[a],
                ]
                extra = [self.chooser.features(a)]
            else:
                target = targets[a] if targets else self.scenario.target(a, self.world)
                own = [q[:n], dq[:n], [self.joint_actions.commanded_opening[a]], tools[a], target]
                extra = []
            vector = np.concatenate([*own, *others, [min(separation[a], SEPARATION_CAP_M)], *extra], dtype=np.float32)
            out[a] = self._masked(a, np.minimum(np.maximum(vector, -OBS_LIMIT, out=vector), OBS_LIMIT, out=vector))
        return out

    def _masked(self, agent: str, vector: np.ndarray) -> np.ndarray | dict:
        """The observation vector, with the action mask beside it when the env was asked for it."""
        if self.settings.mask_in_observation:
            return {"observation": vector, "action_mask": self.action_mask(agent)}
        return vector

    def _opening(self, agent: str) -> float:
        arm = self.world.arms[agent]
        spec = arm.spec
        g = arm.qpos()[spec.arm_dof :]
        return float((np.mean(g) - spec.gripper_closed[0]) / (spec.gripper_open[0] - spec.gripper_closed[0]))

    def state(self, started: bool) -> np.ndarray:
        """Everything for a centralised critic: every arm's joints, velocities, tool and target (none before an
        episode has started), and the parts' positions."""
        chunks = []
        for a in self.agents:
            arm = self.world.arms[a]
            target = self.scenario.target(a, self.world) if started else np.zeros(3)
            chunks += [arm.qpos(), arm.qvel(), np.asarray(arm.tool_pose_world().p, float), target]
        return np.concatenate(chunks).astype(np.float32)
