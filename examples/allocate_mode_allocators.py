"""Allocation as a policy: the `allocate` action mode of the env, played by the coordinator's allocators and by a
random policy, on the same seeded line. The yardstick a learned allocation policy has to beat.

    python examples/allocate_mode_allocators.py --scenario line --arms 2 --max-cycles 300 --episodes 2
"""

from __future__ import annotations

import argparse
from collections.abc import Callable

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy import stats

from coordinator.allocation import ALLOCATORS, make_allocator
from fleet.env import parallel_env
from fleet.env.allocate_mode import allocator_actions

POLICIES = ("random", *ALLOCATORS)


def run_episode(env, seed: int, act: Callable[[object, dict], dict]) -> dict:
    """One episode of `env` from `seed`, each step's actions from `act(env, observations)`; the team return and
    the line's part counts. The env is closed after."""
    obs, _ = env.reset(seed=seed)
    team_return = 0.0
    while env.agents:
        obs, rewards, _, _, _ = env.step(act(env, obs))
        team_return += sum(rewards.values())
    out = {"return": team_return, **line_totals(env)}
    env.close()
    return out


def line_totals(env) -> dict:
    """A allocate-mode env's line so far: parts completed and spawned, tasks failed, sim seconds."""
    totals = env.scenario.book.ledger.totals()
    return {
        "completed": totals["parts_completed"],
        "spawned": totals["parts_spawned"],
        "failed": totals["tasks_failed"],
        "sim_s": env.world.sim_time_s,
    }


def against(runs: list[dict], baseline: list[dict]) -> str:
    """Parts completed against `baseline`'s on the same seeds: the mean difference per episode and its 95% interval
    (Student's t; the seeds' own spread cancels out, as it does not in two separate means)."""
    diffs = np.array([r["completed"] - b["completed"] for r, b in zip(runs, baseline)], float)
    if len(diffs) < 2:
        return f"{diffs.mean():+.2f}"
    half = stats.t.ppf(0.975, len(diffs) - 1) * diffs.std(ddof=1) / np.sqrt(len(diffs))
    return f"{diffs.mean():+.2f} ± {half:.2f}"


def play(
    policy: str,
    scenario: str,
    arms: int | None,
    max_cycles: int,
    seed: int,
    decision_hz: float,
    scene: str | None = None,
) -> dict:
    """One episode (on `scene`, else the scenario's own) played by `policy` (`random` or an allocator's name)."""
    env = parallel_env(
        scene=scene,
        scenario=scenario,
        action_mode="allocate",
        n_arms=arms,
        max_cycles=max_cycles,
        control_hz=decision_hz,
    )
    if policy == "random":
        rng = np.random.default_rng(seed)
        return run_episode(env, seed, lambda env, _: {a: int(rng.integers(env.action_space(a).n)) for a in env.agents})
    allocator = make_allocator(policy, env.scene)
    return run_episode(env, seed, lambda env, _: allocator_actions(env.chooser, allocator, env._options))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", choices=("line", "handover"), default="line")
    parser.add_argument(
        "--scene", help="a bundled scene or scene file (default: the scenario's own, sorting_line for line)"
    )
    parser.add_argument(
        "--arms", type=int, default=None, help="arm count (scenes with an arm row; default: the scene's)"
    )
    parser.add_argument("--max-cycles", type=int, default=300)
    parser.add_argument("--decision-hz", type=float, default=10.0)
    parser.add_argument("--episodes", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    table = Table(
        title=(
            f"allocate mode on {args.scene or args.scenario}: {args.episodes} episode(s) of {args.max_cycles} "
            f"decisions at {args.decision_hz:g} Hz"
        )
    )
    for column in (
        "policy",
        "team return",
        "parts completed / spawned",
        "failed tasks",
        "parts per episode against greedy (same seeds)",
    ):
        table.add_column(column)
    results = {
        policy: [
            play(policy, args.scenario, args.arms, args.max_cycles, args.seed + e, args.decision_hz, args.scene)
            for e in range(args.episodes)
        ]
        for policy in POLICIES
    }
    for policy, runs in results.items():
        table.add_row(
            policy,
            f"{np.mean([r['return'] for r in runs]):.1f}",
            f"{sum(r['completed'] for r in runs)} / {sum(r['spawned'] for r in runs)}",
            str(sum(r["failed"] for r in runs)),
            against(runs, results["greedy"]),
        )
    Console().print(table)


if __name__ == "__main__":
    main()
