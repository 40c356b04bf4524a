"""The examples run (for a few steps) so they never rot. They are independent processes, so they run two at a time
(longest first) from one fixture, and each test reads what its example said."""

import functools
import importlib.util
import json
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from tests.ray_namespace import in_netns

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def example(script: str, *args: str, netns: bool = False) -> list[str]:
    argv = [sys.executable, str(EXAMPLES / script), *args]
    return in_netns(*argv) if netns else argv


def on_ray(script: str, ray_head: str, *args: str) -> list[str]:
    """An RLlib example's run on the tests' Ray head, in its loopback namespace."""
    return example(script, *args, "--address", ray_head, netns=True)


def commands(folder: Path, ray_head: str | None) -> dict[str, list[str]]:
    """Each example's quick run, by name, longest first."""
    out = {}
    if ray_head is not None:
        out["rllib_masked_task_allocator"] = on_ray(
            "rllib_masked_task_allocator.py",
            ray_head,
            *("--iterations", "1", "--batch", "200", "--max-cycles", "40", "--epochs", "1", "--episodes", "1"),
            *("--curve", str(folder / "masked_curve")),
        )
    out["sb3_choice_allocator"] = example(
        "sb3_choice_allocator.py",
        *("--timesteps", "128", "--n-steps", "64", "--max-cycles", "30", "--episodes", "1"),
        *("--imitate", "optimal", "--dagger-rounds", "2", "--dagger-episodes", "1"),
        *("--save", str(folder / "learned.pt2")),
    )
    if ray_head is not None:
        out["rllib_per_arm"] = on_ray(
            "rllib_ppo_reach.py",
            ray_head,
            *("--iterations", "1", "--batch", "200", "--max-cycles", "20", "--epochs", "1", "--env-runners", "1"),
            *("--policies", "per-arm"),
        )
    out["ippo"] = example(
        "train_ippo_reach.py",
        *("--iterations", "2", "--steps", "64", "--max-cycles", "20", "--curve", str(folder / "ippo_curve")),
    )
    out["sb3_reach"] = example(
        "sb3_ppo_reach.py",
        *("--cells", "2", "--cpus", "2", "--timesteps", "1024", "--n-steps", "64", "--max-cycles", "20"),
    )
    out["sb3_pixels"] = example("sb3_pixels_pick.py", "--timesteps", "128", "--n-steps", "64", "--episodes", "2")
    out["allocate_mode"] = example(
        "allocate_mode_allocators.py", "--arms", "2", "--max-cycles", "20", "--episodes", "1"
    )
    out["random_rollout"] = example("random_rollout.py", "--arms", "2", "--episodes", "1", "--max-cycles", "10")
    return out


@pytest.fixture(scope="module")
def ran(request, tmp_path_factory) -> tuple[Path, dict[str, subprocess.CompletedProcess]]:
    """Every example's quick run, two at a time: the folder they wrote in and what each said."""
    folder = tmp_path_factory.mktemp("examples")
    ray_head = request.getfixturevalue("ray_head") if importlib.util.find_spec("ray.rllib") else None
    run = functools.partial(subprocess.run, capture_output=True, text=True, timeout=600, cwd=EXAMPLES)
    todo = commands(folder, ray_head)
    with ThreadPoolExecutor(2) as pool:
        return folder, dict(zip(todo, pool.map(run, todo.values())))


def said(ran, name: str) -> subprocess.CompletedProcess:
    if name not in ran[1]:
        pytest.skip(f"{name} needs ray[rllib] (the rl extra)")
    done = ran[1][name]
    assert done.returncode == 0, done.stderr[-3000:]
    return done


def test_random_rollout_runs(ran):
    assert "episode 0: mean return per arm" in said(ran, "random_rollout").stdout


def test_ippo_training_runs_and_writes_its_curve(ran):
    assert "random policy:" in said(ran, "ippo").stdout
    assert (ran[0] / "ippo_curve.csv").read_text().startswith("iteration,wall_s,agent_steps,mean_return")
    assert (ran[0] / "ippo_curve.png").stat().st_size > 1000


def test_allocate_mode_comparison_runs(ran):
    assert all(p in said(ran, "allocate_mode").stdout for p in ("random", "optimal", "auction", "greedy"))


def test_stable_baselines3_ppo_through_supersuit_trains_a_few_iterations(ran):
    out = said(ran, "sb3_reach").stdout
    assert "trained 1024 agent-steps on 2 cell(s) x 2 arms" in out and "mean return per arm" in out


def test_stable_baselines3_trains_from_pixels_and_is_compared_with_random_on_paired_seeds(ran):
    out = said(ran, "sb3_pixels").stdout
    assert "trained 128 steps from 64x64 pixels" in out and "paired difference" in out and "95% interval" in out


def test_a_policy_trained_with_sb3_in_the_env_is_exported_and_allocates_a_real_line(ran, tmp_path):
    """The trained policy's file, as `fleet run --allocator policy:FILE` takes it: the coordinator process loads it and
    the line runs with the guard and the real controllers."""
    out = said(ran, "sb3_choice_allocator").stdout
    assert "round 0: optimal played" in out and "round 1: policy played" in out  # DAgger from optimal, then PPO
    assert "trained 128 choices" in out and "learned:" in out and "optimal:" in out
    summary = tmp_path / "summary.json"
    policy = ran[0] / "learned.pt2"
    run = ["run", "mixed_infeed", "--duration", "10", "--allocator", f"policy:{policy}", "--summary", str(summary)]
    done = subprocess.run([sys.executable, "-m", "fleet", *run], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads(summary.read_text())["allocator"] == "policy:learned.pt2"


def test_rllib_multi_agent_ppo_trains_a_policy_per_arm_for_an_iteration(ran):
    """A policy per arm on the tests' Ray head, in a namespace whose only interface is loopback (the shared policy is
    the same loop with one policy id)."""
    out = said(ran, "rllib_per_arm").stdout
    assert "iteration 1: episode return" in out and "with policies arm_0, arm_1 on 2 arms" in out


def test_the_masked_task_allocator_trains_with_rllib_and_is_measured_against_the_allocators(ran):
    out = said(ran, "rllib_masked_task_allocator").stdout
    assert all(name in out for name in ("learned", "random", "optimal", "auction", "greedy"))
    assert (ran[0] / "masked_curve.csv").read_text().startswith("iteration,wall_s,env_steps,episode_return")
    assert (ran[0] / "masked_curve.png").stat().st_size > 1000
