"""`fleet bench env`: agent-steps per second of the PettingZoo env, and its step time against raw physics.

Random joint_delta actions. The raw-physics column replays the same run with
nothing but the physics: the drive targets the env set at each step are written
again (the one call any controller makes) and the world is stepped as many
substeps; no actions to translate, no observations, rewards or separations.
Arms held still would understate the physics: moving arms cost PhysX more. The
replay runs on a second world of the same scene, in blocks alternating with the
env's, so a machine whose speed drifts during the run slows both sides alike.
"""

from __future__ import annotations

import json
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fleet.env.cell_env import CellParallelEnv


@dataclass(frozen=True)
class EnvRow:
    arms: int
    scenario: str
    steps: int
    env_s: float
    physics_s: float

    @property
    def agent_steps_per_s(self) -> float:
        return self.steps * self.arms / self.env_s

    @property
    def ratio_to_physics(self) -> float:
        return self.env_s / self.physics_s


BLOCK_STEPS = 20  # env and replay alternate in blocks of this many steps


def bench_env(arms: int, scenario: str = "reach", steps: int = 400, seed: int = 0, distributed: bool = False) -> EnvRow:
    """Time `steps` env steps of random actions, and the physics of the same run replayed (see the module doc)."""
    env = CellParallelEnv(n_arms=arms, scenario=scenario, max_cycles=steps, distributed=distributed)
    replica = CellParallelEnv(n_arms=arms, scenario=scenario, max_cycles=steps)
    rng = np.random.default_rng(seed)
    actions = [
        {a: rng.uniform(-1, 1, env.action_space(a).shape).astype(np.float32) for a in env.possible_agents}
        for _ in range(steps)
    ]
    try:
        recorded = _drive_targets(replica, actions, seed)
        env.reset(seed=seed)
        replica.reset(seed=seed)
        env_s = physics_s = 0.0
        for first in range(0, steps, BLOCK_STEPS):
            start = time.perf_counter()
            for act in actions[first : first + BLOCK_STEPS]:
                env.step(act)
            env_s += time.perf_counter() - start
            physics_s += _replay_s(replica, recorded[first : first + BLOCK_STEPS])
    finally:
        env.close()
        replica.close()
    return EnvRow(arms, scenario, steps, env_s, physics_s)


def _drive_targets(
    env: CellParallelEnv, actions: list[dict[str, np.ndarray]], seed: int
) -> list[dict[str, np.ndarray]]:
    """Every arm's drive targets after each step of the run (a seed repeats the run)."""
    env.reset(seed=seed)
    recorded = []
    for act in actions:
        env.step(act)
        recorded.append({a: env.world.arms[a].drive_targets() for a in env.possible_agents})
    return recorded


def _replay_s(env: CellParallelEnv, recorded: list[dict[str, np.ndarray]]) -> float:
    """Seconds to step `env`'s world through these steps with only the recorded drive targets written."""
    arms = [(a, env.world.arms[a], env.world.arms[a].spec.arm_dof) for a in env.possible_agents]
    still = {a: np.zeros(n) for a, _, n in arms}
    start = time.perf_counter()
    for targets in recorded:
        for a, arm, n in arms:
            q = targets[a]
            arm.set_targets(q[:n], still[a], q[n:])
        env.world.step(env.ticks_per_step)
    return time.perf_counter() - start


@dataclass(frozen=True)
class VectorRow:
    cells: int
    cpus: int
    arms: int
    scenario: str
    steps: int
    agent_steps: int
    wall_s: float

    @property
    def agent_steps_per_s(self) -> float:
        return self.agent_steps / self.wall_s


def bench_vector(cells: int, cpus: int, arms: int = 4, scenario: str = "reach", steps: int = 300) -> VectorRow:
    """`steps` vector steps of `cells` cells in `cpus` worker processes (0: in process), random actions."""
    from fleet.env.vector import vector_env

    venv = vector_env(cells, cpus, scenario=scenario, n_arms=arms, max_cycles=10**6)
    try:
        obs, _ = venv.reset(seed=0)
        rng = np.random.default_rng(0)
        actions = rng.uniform(-1, 1, (steps, obs.shape[0], *venv.action_space.shape)).astype(np.float32)
        start = time.perf_counter()
        for a in actions:
            venv.step(a)
        wall = time.perf_counter() - start
    finally:
        venv.close()
    return VectorRow(cells, cpus, arms, scenario, steps, steps * obs.shape[0], wall)


class BaselineUnavailable(RuntimeError):
    """The robosuite baseline could not be measured with the interpreter given (one line: why)."""


@dataclass(frozen=True)
class RobosuiteRow:
    task: str
    arms: int
    steps: int
    agent_steps_per_s: float
    robosuite: str
    mujoco: str


ROBOSUITE_BASELINE = Path(__file__).with_name("robosuite_baseline.py")  # run as a file: it imports nothing of clawfleet


def bench_robosuite(python: str, steps: int = 400, seed: int = 0, timeout_s: float = 600.0) -> RobosuiteRow:
    """robosuite's TwoArmLift stepped by `python` (an interpreter that has robosuite), in this process's CPU set."""
    try:
        done = subprocess.run(
            [python, str(ROBOSUITE_BASELINE), "--steps", str(steps), "--seed", str(seed)],
            capture_output=True,
            text=True,
            timeout=timeout_s,
            stdin=subprocess.DEVNULL,
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise BaselineUnavailable(f"the robosuite baseline could not run with {python}: {exc}") from None
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]  # robosuite logs to stdout too
    if done.returncode != 0 or not lines:
        why = (done.stderr.strip().splitlines() or [f"exit {done.returncode}"])[-1]
        raise BaselineUnavailable(f"the robosuite baseline failed with {python}: {why}")
    r = json.loads(lines[-1])
    return RobosuiteRow(r["task"], r["arms"], r["steps"], r["agent_steps_per_s"], r["robosuite"], r["mujoco"])
