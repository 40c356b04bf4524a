"""The tasks beyond reach are physically doable through the env's own action interface: a scripted arm
(Pinocchio top-down IK turned into joint_delta actions) grasps its part with friction and drops it in its bin;
the coordinator's allocators, through the `allocate` action mode, complete the handover and line parts."""

import math

import numpy as np
import pytest

from coordinator.allocation import make_allocator
from coordinator.ledger import PIPELINE_DEFAULT
from fleet.env import parallel_env
from fleet.env.allocate_mode import allocator_actions
from fleet.env.scenarios import above
from fleet.sim.world import World
from fleet.sim.world_events import PartSpawned
from robots.frames import yaw_transform
from robots.policy_actions import MAX_DELTA_RAD
from robots.top_down import TopDownIK
from scenes.loader import load_scene


class ScriptedPick:
    """Above the part, down, close, up and over the bin, open: each waypoint by top-down IK, sent as joint steps."""

    def __init__(self, env, agent):
        self.env, self.agent = env, agent
        decl = env.scene.arm(agent)
        self.ik = TopDownIK(env.world.arms[agent].spec, yaw_transform(decl.base.xyz, decl.base.yaw_rad))
        self.tip = env.world.arms[agent].spec.fingertip_below_tool_m
        self.phase, self.closing_steps = "above", 0

    def _yaw(self, info) -> float:
        """The part's yaw (a square box: any quarter turn), nearest the arm's natural yaw."""
        w, x, y, z = info.quaternion_wxyz
        part_yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
        natural = self.ik.natural_yaw(info.position)
        return min(
            (part_yaw + k * math.pi / 2 for k in range(-4, 5)),
            key=lambda c: abs(math.remainder(c - natural, 2 * math.pi)),
        )

    def act(self) -> np.ndarray:
        env, a = self.env, self.agent
        info = env.world.part_info(env.scenario.part[a])
        surface = env.scenario.start_z[a]
        grasp_z = max(surface + info.height_m / 2, surface + self.tip + 0.004)
        q_now = env.joint_targets(a)
        goal, opening, yaw = None, 1.0, self._yaw(info)
        if self.phase == "above":
            goal = np.array([info.position[0], info.position[1], grasp_z + 0.08])
        elif self.phase == "down":
            goal = np.array([info.position[0], info.position[1], grasp_z])
        elif self.phase == "close":
            opening, self.closing_steps = -1.0, self.closing_steps + 1
            if self.closing_steps > 10:
                self.phase = "lift"
        elif self.phase == "lift":
            goal, opening, yaw = above(env.scenario.goal[a]) + [0, 0, 0.05], -1.0, None
        if goal is None:
            return np.array([0.0] * len(q_now) + [opening], np.float32)
        q, _ = self.ik.solve(goal, yaw, q_now)
        step = (q - q_now) / MAX_DELTA_RAD
        if np.max(np.abs(step)) < 0.05:
            self.phase = {"above": "down", "down": "close", "lift": "drop"}[self.phase]
        return np.array([*np.clip(step, -1, 1), opening], np.float32)


def test_pick_place_a_scripted_arm_grasps_its_part_and_drops_it_in_its_bin():
    env = parallel_env(scenario="pick_place", action_mode="joint_delta", n_arms=2, max_cycles=160)
    env.reset(seed=1)
    arms = {a: ScriptedPick(env, a) for a in env.agents}
    succeeded, rewards = set(), {a: [] for a in env.agents}
    while env.agents:
        _, reward, _, _, infos = env.step({a: arms[a].act() for a in env.agents})
        succeeded |= {a for a, i in infos.items() if i["success"]}
        for a, r in reward.items():
            rewards[a].append(r)
    assert succeeded == {"arm_0", "arm_1"}
    for a in rewards:  # the dense reward climbs as the part goes from the belt to the bin
        assert np.mean(rewards[a][-10:]) > np.mean(rewards[a][:10]) + 3.0


def test_pick_place_the_part_stays_put_when_nobody_acts():
    env = parallel_env(scenario="pick_place", action_mode="ee_delta", n_arms=2, max_cycles=30)
    env.reset(seed=0)
    start = {a: env.world.part_info(p).position.copy() for a, p in env.scenario.part.items()}
    still = {a: np.zeros(4, np.float32) + [0, 0, 0, 1] for a in env.agents}
    while env.agents:
        _, _, _, _, infos = env.step(still)
        assert not any(i["success"] for i in infos.values())
    for a, p in env.scenario.part.items():
        assert np.linalg.norm(env.world.part_info(p).position - start[a]) < 0.005  # the belt is stopped for this task


@pytest.mark.parametrize(("scenario", "allocator", "steps"), [("handover", "optimal", 160), ("line", "greedy", 150)])
def test_allocate_mode_the_coordinators_allocators_complete_parts(scenario, allocator, steps):
    env = parallel_env(scenario=scenario, action_mode="allocate", n_arms=2, max_cycles=steps, control_hz=5)
    env.reset(seed=0)
    chooser, policy = env.chooser, make_allocator(allocator, env.scene)
    took = 0
    while env.agents:
        _, _, _, _, infos = env.step(allocator_actions(chooser, policy, env._options))
        took += sum(i["choice"] == "took" for i in infos.values())
    totals = env.scenario.book.ledger.totals()
    assert totals["parts_completed"] >= 1 and took >= 2
    # a moving belt (handover stops it): the coordinator's own dispatcher gives belt deadlines too
    if scenario == "line":
        belt_tasks = [t for t in env.scenario.book.ledger.tasks.values() if t.source == "conveyor"]
        assert belt_tasks and all(t.deadline_s is not None for t in belt_tasks)


def test_allocate_mode_a_choice_of_an_empty_slot_is_refused_with_a_reason_and_a_seed_repeats():
    runs = []
    for _ in range(2):
        env = parallel_env(scenario="line", action_mode="allocate", n_arms=2, max_cycles=60, control_hz=5)
        obs, _ = env.reset(seed=4)
        trace = []
        rng = np.random.default_rng(0)
        while env.agents:
            obs, rewards, _, _, infos = env.step({a: int(rng.integers(0, 5)) for a in env.agents})
            trace.append(
                (
                    tuple(np.concatenate(list(obs.values()))),
                    tuple(rewards.values()),
                    tuple(i["choice"] for i in infos.values()),
                )
            )
        runs.append(trace)
    assert runs[0] == runs[1]
    assert any(c.startswith("refused: slot") for step in runs[0] for c in step[2])


def test_a_line_episode_draws_its_arrivals_from_its_seed_as_fleet_run_does():
    """Seed S gives the arrivals of `fleet run --seed S` (a world built with scene seed S); another seed, others."""

    def spawned(world) -> list[tuple]:
        return [
            (e.part_id, e.feeder, e.type_index, round(e.tick * world.control_dt_s, 3))
            for e in world.events
            if isinstance(e, PartSpawned)
        ]

    env = parallel_env(scene="mixed_infeed", scenario="line", action_mode="allocate", max_cycles=100, control_hz=10)
    by_seed = {}
    for seed in (3, 4, 3):
        env.reset(seed=seed)
        while env.agents:
            env.step({a: 0 for a in env.agents})
        by_seed.setdefault(seed, []).append(spawned(env.world))
    assert by_seed[3][0] == by_seed[3][1] and by_seed[3][0] != by_seed[4][0]
    assert len(by_seed[3][0]) >= 5
    world = World(load_scene("mixed_infeed", seed=3))
    while world.sim_time_s < env.world.sim_time_s:
        world.step()
    assert spawned(world) == by_seed[3][0]


def test_allocate_mode_a_working_arm_is_planned_for_as_the_coordinator_plans_it():
    """A busy arm's estimated time to free (the dispatcher's, from when its task started) reaches the allocators, as in
    `fleet run`: the optimal allocator may leave a task to an arm that is about to be free."""
    env = parallel_env(scene="mixed_infeed", scenario="line", action_mode="allocate", max_cycles=300, control_hz=10)
    allocator = make_allocator("optimal", env.scene)
    env.reset(seed=0)
    seen = []
    while env.agents and not seen:
        env.step(allocator_actions(env.chooser, allocator, env._options))
        seen = [v for v in env.chooser.arm_views() if not v.free and v.free_in_s is not None]
    assert seen and 0.0 <= seen[0].free_in_s < 30.0
    assert env.chooser.dispatcher.arms.busy_until_s[seen[0].name] > env.world.sim_time_s - 1.0


def test_allocate_mode_action_masks_let_a_random_masked_policy_pick_only_real_choices():
    env = parallel_env(scenario="line", action_mode="allocate", n_arms=2, max_cycles=1000, mask_in_observation=True)
    try:
        observations, infos = env.reset(seed=3)
        assert env.observation_space("arm_0")["action_mask"].shape == (5,)
        rng = np.random.default_rng(3)
        took = 0
        while env.agents:
            for a in env.agents:
                mask = observations[a]["action_mask"]
                assert np.array_equal(mask, infos[a]["action_mask"]) and mask[0] == 1, (
                    "the mask in both places; waiting always allowed"
                )
                options = env._options.get(a, [])
                assert mask[1:].sum() == len(options)
                assert all(t.state.value == "pending" and math.isfinite(seconds) for t, seconds in options), (
                    "each valid slot is a task the arm can serve"
                )
            actions = {a: int(rng.choice(np.flatnonzero(observations[a]["action_mask"]))) for a in env.agents}
            observations, _, _, _, infos = env.step(actions)
            choices = [info.get("choice", "") for info in infos.values()]
            assert not any("empty" in c for c in choices), choices
            took += choices.count("took")
        assert took >= 3, "the masked policy took real tasks"
    finally:
        env.close()


def first_choice_episode(seed: int, **options) -> tuple[int, dict[str, float], dict, float]:
    """An episode of a fixed policy (each arm takes its first choice, if it has one): env steps, summed rewards,
    the ledger's totals and the sim time it covered."""
    env = parallel_env(scenario="line", action_mode="allocate", n_arms=2, max_cycles=300, **options)
    try:
        env.reset(seed=seed)
        steps, returns = 0, dict.fromkeys(env.possible_agents, 0.0)
        while env.agents:
            actions = {a: 1 if env._options.get(a) else 0 for a in env.agents}
            _, rewards, _, _, _ = env.step(actions)
            steps += 1
            for a, r in rewards.items():
                returns[a] += r
        return steps, returns, env.chooser.dispatcher.ledger.totals(), env.world.sim_time_s
    finally:
        env.close()


def test_choice_stepping_asks_only_at_choices_and_a_fixed_policy_ends_as_tick_stepping_does():
    ticks, choices = first_choice_episode(4), first_choice_episode(4, choice_steps=True)
    (tick_steps, tick_returns, tick_totals, tick_time), (steps, returns, totals, sim_time) = ticks, choices
    assert (totals, sim_time) == (tick_totals, tick_time), "the same episode: every part's fate, the same length"
    assert returns == pytest.approx(tick_returns), "each arm's return, summed over the periods a step covered"
    assert totals["parts_completed"] >= 1, "the policy got parts done"
    assert steps < tick_steps / 2, f"{steps} choices against {tick_steps} periods"


def test_choice_stepping_is_refused_outside_allocate_mode():
    with pytest.raises(ValueError, match="choice_steps applies to action_mode 'allocate'"):
        parallel_env(scenario="reach", action_mode="joint_delta", choice_steps=True)


def test_action_masks_in_the_observation_are_refused_outside_allocate_mode():
    with pytest.raises(ValueError, match="mask_in_observation applies to action_mode 'allocate'"):
        parallel_env(scenario="reach", action_mode="joint_delta", mask_in_observation=True)


def test_allocate_mode_on_a_fixture_line_asks_for_its_moves_and_pipelines_as_fleet_run_does():
    env = parallel_env(scenario="line", scene="assembly_line", action_mode="allocate", max_cycles=300, control_hz=5)
    env.reset(seed=0)
    chooser, policy = env.chooser, make_allocator("optimal", env.scene)
    assert chooser.grants and all(s.grants.required for s in chooser.skills.values())
    touching = 0
    while env.agents:
        _, _, _, _, infos = env.step(allocator_actions(chooser, policy, env._options))
        touching += sum(i["collision"] for i in infos.values())
    dispatcher = env.scenario.book.dispatcher
    held = dispatcher.grants.held_at_station_s
    # the top waited for its base, the ship for its top
    assert held.get("arm_1", 0) > 0 and held.get("arm_2", 0) > 0, held
    assert touching == 0 and dispatcher.ledger.totals()["parts_completed"] >= 3
    lone = parallel_env(scenario="line", scene="pick_cell", action_mode="allocate", max_cycles=2, control_hz=5)
    lone.reset(seed=0)
    assert not lone.chooser.grants, "a lone arm has nobody to ask, as in fleet run"


def test_allocate_mode_without_a_fixture_still_asks_the_guard_for_every_move_as_fleet_run_does():
    """mixed_infeed's two arms share the rework tray and the kit bin between them: in allocate mode they ask for their
    free moves as in `fleet run` (they used to move unasked there, touched and lost tasks: aborted goals, empty
    grasps)."""
    env = parallel_env(scenario="line", scene="mixed_infeed", action_mode="allocate", max_cycles=600, control_hz=10)
    env.reset(seed=1000)
    chooser, policy = env.chooser, make_allocator("optimal", env.scene)
    assert chooser.grants and chooser.ledger.pipeline == PIPELINE_DEFAULT, "pipelined as fleet run is, by default"
    touching = 0
    while env.agents:
        _, _, _, _, infos = env.step(allocator_actions(chooser, policy, env._options))
        touching += sum(i["collision"] for i in infos.values())
    dispatcher = env.scenario.book.dispatcher
    assert dispatcher.grants.grants_given > 0 and touching == 0
    failed = [t.reason for t in dispatcher.ledger.tasks.values() if t.state.value == "failed"]
    assert not any("aborted" in r or "closed on nothing" in r for r in failed), failed


def test_the_old_names_are_gone_and_a_task_is_only_the_ledger_s():
    """`task=` (the scenario) and `action_mode="task"` were kept one release with a warning; now "task" means only the
    ledger's unit of work, and the old names are refused saying what is valid."""
    with pytest.raises(TypeError, match="task"):
        parallel_env(task="line", n_arms=2)
    with pytest.raises(ValueError, match="action_mode 'task' is not available; valid: .*allocate"):
        parallel_env(scenario="line", n_arms=2, action_mode="task")
