"""The line as a PettingZoo parallel environment: one agent per arm, the same ids as on the bus.

The world is the same SAPIEN world `fleet run` uses (`fleet.physics.world.World`),
stepped in process; minimum separations come from the coordinator's collision
guard (python-fcl), contacts from the physics. Episodes end by truncation at
`max_cycles`; arms never leave mid-episode. `reset(seed)` puts back the world's
first snapshot and draws the targets from the seed, so a seed repeats an episode.

Implemented so far: task `reach` (each arm's claw to its own moving target) with
action modes `joint_delta` (joint target steps) and `ee_delta` (a Cartesian step
of the claw in the world frame, turned into joint steps by damped least squares
on Pinocchio's Jacobian), each plus a gripper command.
"""

from __future__ import annotations

import functools
import math

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv

from coordinator.geometry import ArmGeometry
from coordinator.guard import DEFAULT_MARGIN_M, CollisionGuard
from fleet.physics.render import require_render
from fleet.physics.world import World
from robots.frames import yaw_transform
from robots.kinematics import KinematicModel
from scenes.loader import load_scene
from scenes.schema import Arrival

TASKS = ("reach",)
ACTION_MODES = ("joint_delta", "ee_delta")
RENDER_MODES = ("rgb_array",)
MAX_DELTA_RAD = 0.05  # per step at full action
MAX_EE_STEP_M = 0.01  # ee_delta: the claw's step per control tick at full action
EE_DAMPING = 1e-3
SUCCESS_M = 0.03
OBS_LIMIT = 100.0  # joint velocities are clipped here; positions and angles never come near
TARGET_ORBIT_M = 0.05
TARGET_RAD_PER_S = 0.5
PHYSICS_HZ_FOR_TASK = {"reach": 100.0}  # reaching needs no grasp-grade contact resolution


class CellParallelEnv(ParallelEnv):
    """Arms `arm_0 ... arm_{n-1}` of a scene, each an agent."""

    metadata = {"name": "clawfleet_v0", "render_modes": list(RENDER_MODES), "is_parallelizable": True}

    def __init__(
        self,
        scene: str = "sorting_line",
        n_arms: int | None = 2,
        task: str = "reach",
        action_mode: str = "joint_delta",
        control_hz: float = 20.0,
        max_cycles: int = 200,
        render_mode: str | None = None,
        distributed: bool = False,
    ) -> None:
        for name, value, valid in (("task", task, TASKS), ("action_mode", action_mode, ACTION_MODES)):
            if value not in valid:
                raise ValueError(f"{name} {value!r} is not available; valid: {', '.join(valid)}")
        if render_mode is not None and render_mode not in RENDER_MODES:
            raise ValueError(f"render_mode {render_mode!r}: valid render modes are {', '.join(RENDER_MODES)} (the browser monitor is not there yet)")
        if render_mode == "rgb_array":
            require_render()  # a clear RenderUnavailable where no rendering device exists
        if distributed:
            raise ValueError("distributed=True (actions through Zenoh) is not available yet; use distributed=False")
        if max_cycles < 1:
            raise ValueError("max_cycles must be at least 1")
        base = load_scene(scene, arms=n_arms)
        physics_hz = max(PHYSICS_HZ_FOR_TASK[task], control_hz)
        physics_hz = control_hz * max(1, round(physics_hz / control_hz))
        feeders = [f.model_copy(update={"arrival": Arrival(schedule_s=[])}) for f in base.feeders]  # reach: no parts
        self.scene = base.model_copy(update={"control_hz": control_hz, "physics_hz": physics_hz, "feeders": feeders})
        self.task, self.action_mode, self.max_cycles, self.render_mode = task, action_mode, max_cycles, render_mode
        self.world = World(self.scene)
        self._start = self.world.pack_state()
        self.possible_agents = list(self.world.arms)
        self.agents: list[str] = []
        self.guard = CollisionGuard({
            a.name: ArmGeometry(a.name, self.world.arms[a.name].spec, yaw_transform(a.base.xyz, a.base.yaw_rad)) for a in self.scene.arms
        })
        self._dof = {a: self.world.arms[a].spec.arm_dof for a in self.possible_agents}
        self._kinematics = {a: KinematicModel(self.world.arms[a].spec) for a in self.possible_agents}
        self._base_rotation = {a.name: yaw_transform(a.base.xyz, a.base.yaw_rad)[:3, :3] for a in self.scene.arms}
        self._limits = {a: self.world.arms[a].joint_limits() for a in self.possible_agents}
        self._bases = {a.name: a for a in self.scene.arms}
        self.np_random = np.random.default_rng()
        self.cycles = 0

    # --- spaces -----------------------------------------------------------------------
    @functools.lru_cache(maxsize=None)
    def observation_space(self, agent: str) -> gymnasium.spaces.Box:
        n, others = self._dof[agent], len(self.possible_agents) - 1
        size = n + n + 1 + 3 + 3 + 3 * others + 1
        return gymnasium.spaces.Box(-OBS_LIMIT, OBS_LIMIT, shape=(size,), dtype=np.float32)

    @functools.lru_cache(maxsize=None)
    def action_space(self, agent: str) -> gymnasium.spaces.Box:
        size = (3 if self.action_mode == "ee_delta" else self._dof[agent]) + 1
        return gymnasium.spaces.Box(-1.0, 1.0, shape=(size,), dtype=np.float32)

    # --- episode ------------------------------------------------------------------------
    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self.np_random = np.random.default_rng(seed)
        self.world.restore_state(self._start)
        self.agents = list(self.possible_agents)
        self.cycles = 0
        self._targets_q = {a: self.world.arms[a].qpos()[: self._dof[a]].copy() for a in self.agents}
        self._opening = {a: 1.0 for a in self.agents}
        self._centres, self._phases = {}, {}
        for a in self.agents:
            arm = self._bases[a]
            forward, side, up = self.np_random.uniform([0.25, -0.15, 0.12], [0.45, 0.15, 0.30])
            c, s = math.cos(arm.base.yaw_rad), math.sin(arm.base.yaw_rad)
            self._centres[a] = np.array([arm.base.xyz[0] + c * forward - s * side, arm.base.xyz[1] + s * forward + c * side, up])
            self._phases[a] = float(self.np_random.uniform(0, 2 * math.pi))
        return self._observe(), {a: {"success": False, "collision": False} for a in self.agents}

    def target(self, agent: str) -> np.ndarray:
        """Where `agent`'s target is now (it circles its centre)."""
        angle = self._phases[agent] + TARGET_RAD_PER_S * self.world.sim_time_s
        return self._centres[agent] + TARGET_ORBIT_M * np.array([math.cos(angle), math.sin(angle), 0.0])

    def step(self, actions: dict[str, np.ndarray]):
        for a in self.agents:
            action = np.clip(np.asarray(actions.get(a, np.zeros(self.action_space(a).shape)), float), -1.0, 1.0)
            lower, upper = self._limits[a]
            n = self._dof[a]
            self._targets_q[a] = np.clip(self._targets_q[a] + self._joint_step(a, action[:-1]), lower[:n], upper[:n])
            self._opening[a] = (action[-1] + 1.0) / 2.0
            arm = self.world.arms[a]
            arm.set_targets(self._targets_q[a], np.zeros(n), arm.spec.gripper_targets(self._opening[a]))
        self.world.step()
        self.cycles += 1
        touching = {name for pair in self.world.inter_arm_contacts() for name in pair}
        separation = self._separations()
        tools = self._tools()
        rewards, infos = {}, {}
        distances = {a: float(np.linalg.norm(tools[a] - self.target(a))) for a in self.agents}
        successes = {a: d < SUCCESS_M for a, d in distances.items()}
        team = sum(successes.values()) / max(1, len(self.agents))
        for a in self.agents:
            distance = distances[a]
            action = np.asarray(actions.get(a, 0.0), float)
            near_miss = separation[a] < DEFAULT_MARGIN_M
            rewards[a] = float(
                -distance + (1.0 if successes[a] else 0.0) + 0.1 * team
                - (0.5 if near_miss else 0.0) - (1.0 if a in touching else 0.0) - 0.01 * float(np.sum(action**2))
            )
            infos[a] = {"success": successes[a], "collision": a in touching, "near_miss": near_miss, "distance_m": distance}
        done = self.cycles >= self.max_cycles
        terminations = {a: False for a in self.agents}
        truncations = {a: done for a in self.agents}
        observations = self._observe(separation, tools)
        if done:
            self.agents = []
        return observations, rewards, terminations, truncations, infos

    def _joint_step(self, agent: str, action: np.ndarray) -> np.ndarray:
        """Joint target change for one action: direct, or from a claw step by damped least squares."""
        if self.action_mode == "joint_delta":
            return action * MAX_DELTA_RAD
        km = self._kinematics[agent]
        step_base = self._base_rotation[agent].T @ (action * MAX_EE_STEP_M)  # world -> base frame
        jacobian = km.frame_jacobian(km.full_q(self._targets_q[agent]))[:3, km.arm_q_index]
        return jacobian.T @ np.linalg.solve(jacobian @ jacobian.T + EE_DAMPING * np.eye(3), step_base)

    # --- observations -----------------------------------------------------------------
    def _tool(self, agent: str) -> np.ndarray:
        return np.asarray(self.world.arms[agent].tool_pose_world().p, float)

    def _separations(self) -> dict[str, float]:
        """Each arm's distance to its nearest other arm (python-fcl, the coordinator's guard)."""
        if len(self.possible_agents) < 2:
            return {a: math.inf for a in self.possible_agents}
        for a in self.possible_agents:
            self.guard.set_state(a, self.world.arms[a].qpos()[: self._dof[a]])
        return self.guard.nearest_other_m()

    def _tools(self) -> dict[str, np.ndarray]:
        """Every arm's claw position now (world frame)."""
        return {a: self._tool(a) for a in self.possible_agents}

    def _observe(self, separation: dict[str, float] | None = None, tools: dict[str, np.ndarray] | None = None) -> dict[str, np.ndarray]:
        separation = separation or self._separations()
        tools = tools or self._tools()
        out = {}
        for a in self.agents:
            arm = self.world.arms[a]
            q, dq, n = arm.qpos(), arm.qvel(), self._dof[a]
            others = [tools[b] for b in self.possible_agents if b != a]
            out[a] = np.concatenate([
                q[:n], dq[:n], [self._opening[a]], tools[a], self.target(a), *others, [min(separation[a], 10.0)],
            ]).clip(-OBS_LIMIT, OBS_LIMIT).astype(np.float32)
        return out

    def state(self) -> np.ndarray:
        """Everything for a centralised critic: every arm's joints, velocities, tool and target."""
        chunks = []
        for a in self.possible_agents:
            arm = self.world.arms[a]
            chunks += [arm.qpos(), arm.qvel(), self._tool(a), self.target(a) if self._centres else np.zeros(3)]
        return np.concatenate(chunks).astype(np.float32)

    def render(self):
        if self.render_mode is None:
            return None
        require_render()

    def close(self) -> None:
        pass
