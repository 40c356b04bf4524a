"""LeRobot's own Python for the twin's tests: the virtualenv `bash scripts/install-lerobot` makes (the README's test
command runs it), or the one `CLAWFLEET_LEROBOT_PYTHON` names."""

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]


def lerobot_python() -> Path | None:
    named = os.environ.get("CLAWFLEET_LEROBOT_PYTHON")
    python = Path(named) if named else REPO / ".venv-lerobot" / "bin" / "python"
    return python if python.exists() else None


@pytest.fixture
def lerobot() -> Path:
    """LeRobot's Python. Without it a test is skipped with the command that makes it; under CI (`CI` set) it fails
    instead: CI runs the README's test command, which installs it, so a missing one is a broken install."""
    python = lerobot_python()
    if python is None:
        why = "needs LeRobot's virtualenv: bash scripts/install-lerobot"
        if os.environ.get("CI"):
            pytest.fail(f"{why} (the test command installs it; CI must not skip this)")
        pytest.skip(why)
    return python
