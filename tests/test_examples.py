"""The examples run (for a few steps) so they never rot."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.ray_namespace import in_netns

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_random_rollout_runs():
    result = subprocess.run(
        [sys.executable, str(EXAMPLES / "random_rollout.py"), "--arms", "2", "--episodes", "1", "--max-cycles", "10"],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr
    assert "episode 0: mean return per arm" in result.stdout


def test_ippo_training_runs_and_writes_its_curve(tmp_path):
    result = subprocess.run(
        [
            sys.executable,
            str(EXAMPLES / "train_ippo_reach.py"),
            "--iterations",
            "2",
            "--steps",
            "64",
            "--max-cycles",
            "20",
            "--curve",
            str(tmp_path / "curve"),
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert "random policy:" in result.stdout
    assert (tmp_path / "curve.csv").read_text().startswith("iteration,wall_s,agent_steps,mean_return")
    assert (tmp_path / "curve.png").stat().st_size > 1000


def test_allocate_mode_comparison_runs():
    result = subprocess.run(
        [
            sys.executable,
            str(EXAMPLES / "allocate_mode_allocators.py"),
            "--arms",
            "2",
            "--max-cycles",
            "20",
            "--episodes",
            "1",
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert all(p in result.stdout for p in ("random", "optimal", "auction", "greedy"))


def test_stable_baselines3_ppo_through_supersuit_trains_a_few_iterations():
    result = subprocess.run(
        [
            sys.executable,
            str(EXAMPLES / "sb3_ppo_reach.py"),
            "--cells",
            "2",
            "--cpus",
            "2",
            "--timesteps",
            "1024",
            "--n-steps",
            "64",
            "--max-cycles",
            "20",
        ],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert "trained 1024 agent-steps on 2 cell(s) x 2 arms" in result.stdout and "mean return per arm" in result.stdout


def test_a_policy_trained_with_sb3_in_the_env_is_exported_and_allocates_a_real_line(tmp_path):
    """The trained policy's file, as `fleet run --allocator policy:FILE` takes it: the coordinator process loads it and
    the line runs with the guard and the real controllers."""
    policy = tmp_path / "learned.pt2"
    quick = ["--timesteps", "256", "--n-steps", "64", "--max-cycles", "60", "--episodes", "1", "--save", str(policy)]
    trained = subprocess.run(
        [sys.executable, str(EXAMPLES / "sb3_choice_allocator.py"), *quick],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=EXAMPLES,
    )
    assert trained.returncode == 0, trained.stderr[-3000:]
    assert "trained 256 choices" in trained.stdout and "learned:" in trained.stdout and "optimal:" in trained.stdout
    summary = tmp_path / "summary.json"
    run = ["run", "mixed_infeed", "--duration", "10", "--allocator", f"policy:{policy}", "--summary", str(summary)]
    done = subprocess.run([sys.executable, "-m", "fleet", *run], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads(summary.read_text())["allocator"] == "policy:learned.pt2"


def test_rllib_multi_agent_ppo_trains_a_policy_per_arm_for_an_iteration(ray_head):
    """A policy per arm on the tests' Ray head, in a namespace whose only interface is loopback (the shared policy is
    the same loop with one policy id)."""
    pytest.importorskip("ray.rllib")
    quick = ["--iterations", "1", "--batch", "200", "--max-cycles", "20", "--epochs", "1", "--env-runners", "1"]
    done = subprocess.run(
        in_netns(
            sys.executable, str(EXAMPLES / "rllib_ppo_reach.py"), *quick, "--policies", "per-arm", "--address", ray_head
        ),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert "iteration 1: episode return" in done.stdout and "with policies arm_0, arm_1 on 2 arms" in done.stdout


def test_the_masked_task_allocator_trains_with_rllib_and_is_measured_against_the_allocators(tmp_path, ray_head):
    pytest.importorskip("ray.rllib")
    argv = [
        "--iterations",
        "1",
        "--batch",
        "200",
        "--max-cycles",
        "40",
        "--epochs",
        "1",
        "--episodes",
        "1",
        "--curve",
        str(tmp_path / "curve"),
        "--address",
        ray_head,
    ]
    done = subprocess.run(
        in_netns(sys.executable, str(EXAMPLES / "rllib_masked_task_allocator.py"), *argv),
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert all(name in done.stdout for name in ("learned", "random", "optimal", "auction", "greedy"))
    assert (tmp_path / "curve.csv").read_text().startswith("iteration,wall_s,env_steps,episode_return")
    assert (tmp_path / "curve.png").stat().st_size > 1000
