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
