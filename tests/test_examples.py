"""The examples run (for a few steps) so they never rot."""

import subprocess
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_random_rollout_runs():
    result = subprocess.run(
        [sys.executable, str(EXAMPLES / "random_rollout.py"), "--arms", "2", "--episodes", "1", "--max-cycles", "10"],
        capture_output=True, text=True, timeout=300,
    )
    assert result.returncode == 0, result.stderr
    assert "episode 0: mean return per arm" in result.stdout


def test_ippo_training_runs_and_writes_its_curve(tmp_path):
    result = subprocess.run(
        [sys.executable, str(EXAMPLES / "train_ippo_reach.py"), "--iterations", "2", "--steps", "64", "--max-cycles", "20",
         "--curve", str(tmp_path / "curve")],
        capture_output=True, text=True, timeout=600,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert "random policy:" in result.stdout
    assert (tmp_path / "curve.csv").read_text().startswith("iteration,wall_s,agent_steps,mean_return")
    assert (tmp_path / "curve.png").stat().st_size > 1000


def test_task_mode_comparison_runs():
    result = subprocess.run(
        [sys.executable, str(EXAMPLES / "task_mode_allocators.py"), "--arms", "2", "--max-cycles", "20", "--episodes", "1"],
        capture_output=True, text=True, timeout=300,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert all(p in result.stdout for p in ("random", "optimal", "auction", "greedy"))


def test_stable_baselines3_ppo_through_supersuit_trains_a_few_iterations():
    result = subprocess.run(
        [sys.executable, str(EXAMPLES / "sb3_ppo_reach.py"), "--cells", "2", "--cpus", "2", "--timesteps", "1024", "--n-steps", "64",
         "--max-cycles", "20"],
        capture_output=True, text=True, timeout=600,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert "trained 1024 agent-steps on 2 cell(s) x 2 arms" in result.stdout and "mean return per arm" in result.stdout
