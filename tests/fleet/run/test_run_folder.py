"""A run's folder holds its bus's logins and keys: private, gone when the launcher ends however it ends, and
cleaned at the next start after a launcher was killed outright."""

import stat
import subprocess
import sys
from pathlib import Path

from fleet.run.launcher import Launcher, RunOptions
from fleet.run.run_folder import OWNER_FILE, SECRETS, clean_abandoned, close_run_folder, make_run_folder

KILLED_LAUNCHER = """
import os, signal
from fleet.run.launcher import Launcher, RunOptions
launcher = Launcher(RunOptions(scene="pick_cell"))
print(launcher.dir, flush=True)
os.kill(os.getpid(), signal.SIGKILL)
"""


def test_a_killed_launcher_s_folder_is_private_and_the_next_start_removes_it():
    result = subprocess.run([sys.executable, "-c", KILLED_LAUNCHER], capture_output=True, text=True, timeout=120)
    assert result.returncode == -9, result.stderr
    folder = Path(result.stdout.strip())
    assert (folder / SECRETS).is_dir() and any((folder / SECRETS).rglob("*.json5")), "the bus's logins were written"
    assert stat.S_IMODE(folder.stat().st_mode) == 0o700
    with Launcher(RunOptions(scene="pick_cell")) as launcher:  # the next start, before anything runs
        assert not folder.exists()
        assert launcher.dir.exists()
    assert not launcher.dir.exists()


def test_a_live_launcher_s_folder_is_left_alone_and_kept_logs_lose_only_their_secrets(tmp_path):
    mine = make_run_folder()  # this process is its launcher, alive
    try:
        assert mine not in clean_abandoned() and mine.exists()
        (mine / SECRETS).mkdir()
        (mine / SECRETS / "monitor.json5").write_text("{}")
        (mine / "sim.log").write_text("what the sim said")
        close_run_folder(mine, keep_logs=True)
        assert (mine / "sim.log").exists() and not (mine / SECRETS).exists() and not (mine / OWNER_FILE).exists()
        assert mine not in clean_abandoned()  # kept logs are the user's: no owner mark, never removed
    finally:
        close_run_folder(mine, keep_logs=False)
    assert not mine.exists()
