"""The line as a PettingZoo parallel environment: one agent per arm, the same ids as on the bus.

The world is the same SAPIEN world `fleet run` uses (`fleet.sim.world.World`),
stepped in process (or, with `distributed=True`, with each arm's action turned into
joint targets by its own process over Zenoh); minimum separations come from the
coordinator's collision guard (python-fcl), contacts from the physics, tasks in
`allocate` mode from the coordinator's ledger and eligibility rules. Episodes end by
truncation at `max_cycles`; arms never leave mid-episode. `reset(seed)` puts back
the world's packed start and draws the episode from the seed, so a seed repeats it.
"""

from __future__ import annotations

import functools
import math

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv

from coordinator.geometry import ArmGeometry
from coordinator.guard import DEFAULT_MARGIN_M, CollisionGuard
from fleet.common.scene_loading import load_checked_scene
from fleet.env.actions import JointActions, choice_rewards
from fleet.env.allocate_mode import TaskChooser
from fleet.env.camera_views import EnvCameras, chosen_cameras
from fleet.env.choice_steps import run_on_to_a_choice
from fleet.env.env_sight import EnvSight
from fleet.env.limits import (
    CONTACT_PENALTY,
    LIMIT_PENALTY,
    NEAR_MISS_PENALTY,
    SEPARATION_CAP_M,
    TEAM_WEIGHT,
)
from fleet.env.observations import EnvObserver, ObservationSettings
from fleet.env.scenarios import SCENARIOS, Scenario, make_scenario
from fleet.env.snapshot_episode import resume_chooser, start_from_snapshot
from fleet.sim.render import require_render
from fleet.sim.world import World
from robots.frames import yaw_transform
from robots.policy_actions import CONTINUOUS_MODES

ACTION_MODES = (*CONTINUOUS_MODES, "allocate")
ALLOCATE_SCENARIOS = ("handover", "line")  # tasks whose parts make ledger tasks to choose from
RENDER_MODES = ("human", "rgb_array")
# what an agent observes: its arm, the others and its choices (`cell`); or only its choices (`choices`, allocate mode:
# what the coordinator's `policy:FILE` allocator builds in the running line, so such a policy can be deployed)
OBSERVE = ("cell", "choices")
DEFAULT_SCENE = {"handover": "handover"}  # other tasks: sorting_line


class CellParallelEnv(ParallelEnv):
    """Arms `arm_0 ... arm_{n-1}` of a scene, each an agent."""

    metadata = {"name": "clawfleet_v0", "render_modes": list(RENDER_MODES), "is_parallelizable": True}

    def __init__(
        self,
        scene: str | None = None,
        n_arms: int | None = None,
        scenario: str = "reach",
        action_mode: str = "joint_delta",
        control_hz: float = 20.0,
        max_cycles: int = 200,
        render_mode: str | None = None,
        distributed: bool = False,
        monitor_port: int = 8080,
        mask_in_observation: bool = False,
        choice_steps: bool = False,
        observe: str = "cell",
        cameras: bool | list = False,
        perception: str = "truth",
    ) -> None:
        self._init_kwargs = dict(
            scene=scene,
            n_arms=n_arms,
            scenario=scenario,
            action_mode=action_mode,
            control_hz=control_hz,
            max_cycles=max_cycles,
            render_mode=render_mode,
            distributed=distributed,
            monitor_port=monitor_port,
            mask_in_observation=mask_in_observation,
            choice_steps=choice_steps,
            observe=observe,
            cameras=cameras,
            perception=perception,
        )
        check_perception(perception, action_mode)
        check_options(scenario, action_mode, render_mode, max_cycles, control_hz, distributed)
        check_allocate_options(action_mode, mask_in_observation, choice_steps, observe)
        self.mask_in_observation, self.choice_steps, self.observe = mask_in_observation, choice_steps, observe
        if render_mode == "rgb_array" or cameras or perception == "cameras":
            require_render()  # a clear RenderUnavailable, naming what to install, where no rendering device exists
        scene = scene or DEFAULT_SCENE.get(scenario, "sorting_line")
        base = load_checked_scene(scene, arms=n_arms)  # None: the scene's own count; a fixed-arm scene refuses another
        self.possible_agents = [a.name for a in base.arms]
        self.scenario: Scenario = make_scenario(scenario, self.possible_agents)
        self.scenario.check(base)
        prepared = self.scenario.prepare(base)
        self.scenario_name, self.action_mode = scenario, action_mode
        self.max_cycles, self.render_mode = max_cycles, render_mode
        if action_mode == "allocate":  # skills run at the scene's control rate; an env step is one decision
            self.scene = prepared
            self.ticks_per_step = max(1, round(prepared.control_hz / control_hz))
        else:
            physics_hz = control_hz * max(1, round(max(self.scenario.physics_hz, control_hz) / control_hz))
            self.scene = prepared.model_copy(update={"control_hz": control_hz, "physics_hz": physics_hz})
            self.ticks_per_step = 1
        self._build_cell(action_mode, distributed, scene, n_arms, monitor_port, perception)
        self._build_views(cameras, observe, mask_in_observation)

    def _build_views(self, cameras: bool | list, observe: str, mask_in_observation: bool) -> None:
        """The cameras asked for (and those rgb_array renders), and the observer of the cell's agents."""
        chosen = chosen_cameras(self.scene.cameras, cameras)  # images in the observations
        self._shown_cameras = shown = chosen or (self.scene.cameras if self.render_mode == "rgb_array" else [])
        self.cameras = EnvCameras(self.world, shown, self.possible_agents) if shown else None
        settings = ObservationSettings(observe, self.action_mode, mask_in_observation, camera_obs=bool(chosen))
        parts = (self.world, self.guard, self.scenario, self.chooser, self.joint_actions, self.cameras)
        self.observer = EnvObserver(settings, self.possible_agents, *parts)

    def use_world(self, world: World) -> None:
        """A new world (an episode from a snapshot is built afresh) handed to everything that drives or sees it."""
        self.world = self.observer.world = world
        for part in (self.chooser, self.joint_actions):
            if part is not None:
                part.world = world
        if self.cameras is not None:  # its render mirror copies this world's bodies
            self.cameras = self.observer.cameras = EnvCameras(world, self._shown_cameras, self.possible_agents)
        if self.sight is not None:
            self.sight.use_world(world)

    def _build_cell(
        self, action_mode: str, distributed: bool, scene: str, n_arms: int | None, monitor_port: int, perception: str
    ) -> None:
        """The world, the guard over its arms, the action translators, the allocate mode's chooser and the actuators."""
        self.world = World(self.scene)
        self._start = self.world.pack_state()
        self.agents: list[str] = []
        placements = {a.name: yaw_transform(a.base.xyz, a.base.yaw_rad) for a in self.scene.arms}
        self.guard = CollisionGuard(
            {a: ArmGeometry(a, self.world.arms[a].spec, placements[a]) for a in self.possible_agents}
        )
        # `perception="cameras"`: the allocate mode's parts are those the fixed cameras show (`fleet.env.env_sight`)
        self.sight = EnvSight(self.world, self.scene) if perception == "cameras" else None
        self.chooser = (
            TaskChooser(self.scene, self.world, self.possible_agents, self.sight) if action_mode == "allocate" else None
        )
        self.actuator = None
        if distributed:
            from fleet.env.distributed import RemoteActuators  # the bus only when asked for

            self.actuator = RemoteActuators(scene, n_arms, self.possible_agents, action_mode)
        self.joint_actions = (
            None
            if action_mode == "allocate"
            else JointActions(self.world, self.possible_agents, placements, action_mode, self.actuator)
        )
        self.monitor = None
        self.monitor_port = monitor_port
        self.np_random = np.random.default_rng()
        self.cycles = 0
        self._options: dict = {}

    def __reduce__(self):
        """Pickled as its settings: a copy (a vector env's worker process) is a fresh cell of the same kind."""
        return (_rebuild, (self._init_kwargs,))

    # --- spaces -----------------------------------------------------------------------

    def joint_targets(self, agent: str) -> np.ndarray:
        """The arm joint targets an agent's actions have reached (continuous action modes)."""
        return self.joint_actions.joint_targets(agent)

    @functools.cache
    def observation_space(self, agent: str) -> gymnasium.spaces.Space:
        return self.observer.observation_space(agent)

    @functools.cache
    def action_space(self, agent: str) -> gymnasium.spaces.Space:
        return self.observer.action_space(agent)

    def action_mask(self, agent: str) -> np.ndarray:
        return self.observer.action_mask(agent)  # allocate mode: 1 where an action chooses something real now

    def state(self) -> np.ndarray:
        """Everything for a centralised critic (`EnvObserver.state`)."""
        return self.observer.state(started=bool(self.agents or self.cycles))

    # --- episode ------------------------------------------------------------------------
    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            self.np_random = np.random.default_rng(seed)
        self.world.restore_state(self._start)
        # each episode its own arrivals: seed S gives those of `fleet run --seed S`; no seed, a draw from the env's
        # stream
        feeder_seed = seed if seed is not None else int(self.np_random.integers(2**32))
        self.world.reseed_feeders(feeder_seed)
        self.agents = list(self.possible_agents)
        self.cycles = 0
        self.scenario.home_tool = self.observer.tools()
        self.scenario.reset(self.world, self.np_random)
        snapshot = (options or {}).get("snapshot")
        if snapshot is not None and self.sight is not None:
            raise ValueError('perception="cameras" cannot start an episode from a snapshot yet (docs/perception.md)')
        if self.sight is not None:  # the first frame, of the episode's first tick
            self.sight.reset()
            self.sight.after_tick(self.world, self.scenario.book.log)
        moment = start_from_snapshot(self, snapshot, feeder_seed) if snapshot is not None else None
        start_q = {a: self.world.arms[a].qpos()[: self.observer.dof[a]] for a in self.possible_agents}
        if self.joint_actions is not None:
            self.joint_actions.reset(start_q)
        if self.actuator is not None:
            self.actuator.reset(start_q)
        if self.chooser is not None:
            self.chooser.reset(self.scenario.book.dispatcher)
            if moment is not None:
                resume_chooser(self.chooser, moment)
        self._options = self.chooser.choices() if self.chooser else {}
        observations = self.observer.observe(self.agents)  # places the guard's arms, which the human render draws
        if self.render_mode == "human":
            self.render()
        infos = {a: {"success": False, "collision": False} for a in self.agents}
        if self.chooser is not None:
            for a in self.agents:
                infos[a]["action_mask"] = self.action_mask(a)
        return observations, infos

    def step(self, actions: dict[str, np.ndarray]):
        rewards, infos, seen = self._step_once(actions)
        if self.choice_steps:
            rewards, infos, seen = run_on_to_a_choice(
                lambda: self._step_once({}),
                lambda: any(self._options.get(a) for a in self.agents),
                lambda: self.cycles < self.max_cycles,
                (rewards, infos, seen),
            )
        done = self.cycles >= self.max_cycles
        terminations = {a: False for a in self.agents}
        truncations = {a: done for a in self.agents}
        observations = self.observer.observe(self.agents, *seen)
        if done:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return observations, rewards, terminations, truncations, infos

    def _act(self, actions: dict) -> tuple[dict[str, bool], dict[str, float]]:
        """This step's actions applied: the allocate mode's choices, or the joint actions."""
        if self.chooser is not None:
            self._choice_results = self.chooser.choose(actions, self._options)
            return {}, {}
        return self.joint_actions.apply(actions) if self.agents else ({}, {})

    def _step_once(self, actions: dict) -> tuple[dict, dict, tuple]:
        """One env period: the actions applied, the world stepped; each agent's reward and info, and what the
        observations are made of (separations, tools, joints, targets)."""
        limit_hits, effort = self._act(actions)
        for _ in range(self.ticks_per_step):
            if self.chooser is not None:
                self.chooser.command()
            self.world.step()
            self.scenario.on_tick(self.world)
            if self.sight is not None:
                self.sight.after_tick(self.world, self.scenario.book.log)
            if self.chooser is not None:
                self.chooser.report()
        self.cycles += 1
        touching = {name for pair in self.world.inter_arm_contacts() for name in pair}
        joints = self.observer.joints()
        separation, tools = self.observer.separations(joints), self.observer.tools()
        targets = {a: self.scenario.target(a, self.world) for a in self.agents} if self.chooser is None else {}
        if self.chooser is None:
            rewards, successes = self.scenario.progress(self.world, tools, targets)
        else:
            rewards, successes = choice_rewards(self.chooser, self.scenario.book.net_gain(), self.agents)
        infos = shaped_outcomes(self.agents, rewards, successes, separation, touching, limit_hits, effort)
        if self.chooser is None:
            for a in self.agents:
                infos[a]["distance_m"] = math.dist(tools[a], targets[a])
        else:
            for a, what in self._choice_results.items():
                infos[a]["choice"] = what
            self._options = self.chooser.choices()
            for a in self.agents:
                infos[a]["action_mask"] = self.action_mask(a)
        return rewards, infos, (separation, tools, joints, targets)

    # --- observations -----------------------------------------------------------------

    # --- watching ---------------------------------------------------------------------
    def render(self):
        if self.render_mode is None:
            return None
        if self.render_mode == "rgb_array":
            if self.cameras is None:
                raise ValueError('render_mode="rgb_array" needs a scene with a fixed camera (docs/cameras.md)')
            return self.cameras.picture()
        if self.monitor is None:
            from fleet.env.watch import EnvMonitor  # viser only when someone watches

            self.monitor = EnvMonitor(self.scene, port=self.monitor_port)
            print(f"clawfleet env: watch at {self.monitor.url}", flush=True)
        self.monitor.update(self.world, self.guard)
        return None

    def close(self) -> None:
        if self.monitor is not None:
            self.monitor.close()
            self.monitor = None
        if self.actuator is not None:
            self.actuator.close()
            self.actuator = None


def _rebuild(kwargs: dict) -> CellParallelEnv:
    return CellParallelEnv(**kwargs)


def check_perception(perception: str, action_mode: str) -> None:
    """Where the allocate mode's parts come from: the truth, or the fixed cameras (only the allocate mode has parts to
    see: its skills and dispatcher); anything else refused with what is valid."""
    if perception not in ("truth", "cameras"):
        raise ValueError(f"perception {perception!r} is not available; valid: truth, cameras")
    if perception == "cameras" and action_mode != "allocate":
        raise ValueError(
            f"perception='cameras' applies to action_mode 'allocate' (parts to see); {action_mode!r} has none"
        )


def check_allocate_options(action_mode: str, mask_in_observation: bool, choice_steps: bool, observe: str) -> None:
    """Refuse the allocate mode's own options in another mode, and an unknown `observe`, each with what is valid."""
    if observe not in OBSERVE:
        raise ValueError(f"observe {observe!r} is not available; valid: {', '.join(OBSERVE)}")
    if action_mode == "allocate":
        return
    for name, value, why in (
        ("mask_in_observation", mask_in_observation, "choices that can be invalid"),
        ("choice_steps", choice_steps, "choices to step between"),
        ("observe='choices'", observe == "choices", "choices to observe"),
    ):
        if value:
            raise ValueError(f"{name} applies to action_mode 'allocate' ({why}); {action_mode!r} has none")


def check_options(
    scenario: str,
    action_mode: str,
    render_mode: str | None,
    max_cycles: int,
    control_hz: float,
    distributed: bool = False,
) -> None:
    """Refuse impossible settings up front, each with what is valid."""
    for name, value, valid in (("scenario", scenario, tuple(SCENARIOS)), ("action_mode", action_mode, ACTION_MODES)):
        if value not in valid:
            raise ValueError(f"{name} {value!r} is not available; valid: {', '.join(valid)}")
    if action_mode == "allocate" and scenario not in ALLOCATE_SCENARIOS:
        raise ValueError(
            f"action_mode 'allocate' chooses among the line's pending tasks; scenario {scenario!r} has none to choose "
            f"(valid with 'allocate': {', '.join(ALLOCATE_SCENARIOS)})"
        )
    if distributed and action_mode not in CONTINUOUS_MODES:
        raise ValueError(
            f"distributed=True carries continuous actions ({', '.join(CONTINUOUS_MODES)}) to the arms' processes; "
            f"in action_mode {action_mode!r} the skills run in process: use distributed=False"
        )
    if render_mode is not None and render_mode not in RENDER_MODES:
        raise ValueError(f"render_mode {render_mode!r}: valid render modes are {', '.join(RENDER_MODES)}")
    if max_cycles < 1:
        raise ValueError("max_cycles must be at least 1")
    if not control_hz > 0:
        raise ValueError("control_hz must be positive")


def shaped_outcomes(
    agents: list[str],
    rewards: dict[str, float],
    successes: dict[str, bool],
    separation: dict[str, float],
    touching: set[str],
    limit_hits: dict[str, bool],
    effort: dict[str, float],
) -> dict[str, dict]:
    """One period's task rewards shaped in place (the team's successes shared; near misses, contacts, joint limits
    and effort charged) and each agent's info."""
    team = sum(successes.values()) / max(1, len(agents))
    infos = {}
    for a in agents:
        near_miss, at_limit = separation[a] < DEFAULT_MARGIN_M, limit_hits.get(a, False)
        rewards[a] = float(
            rewards[a]
            + TEAM_WEIGHT * team
            - (NEAR_MISS_PENALTY if near_miss else 0.0)
            - (CONTACT_PENALTY if a in touching else 0.0)
            - (LIMIT_PENALTY if at_limit else 0.0)
            - effort.get(a, 0.0)
        )
        infos[a] = {
            "success": successes[a],
            "collision": a in touching,
            "near_miss": near_miss,
            "separation_m": min(separation[a], SEPARATION_CAP_M),
            "joint_limit": at_limit,
        }
    return infos
