"""A run's folder in the temporary folder: the bus's logins and keys, the nodes' logs, the sim's spool.

It is made private (mode 0700, as `tempfile.mkdtemp` makes it) and carries its launcher's process id. When the
launcher ends, in any way, the folder goes, or where its logs are kept (`--keep-logs`, a node that crashed) its
secrets go (`bus/`). A launcher killed outright (SIGKILL) cannot clean up: the next launcher removes the folders
whose launcher is no longer running.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

PREFIX = "clawfleet-run-"
OWNER_FILE = "launcher.pid"  # "<pid> <start time in clock ticks>": the launcher, even after its pid is reused
SECRETS = "bus"  # the logins, passwords and TLS keys of the run's bus


def _started(pid: int) -> str:
    """When process `pid` started (clock ticks since boot, from /proc), or "" where that cannot be read."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return ""
    return stat.rsplit(")", 1)[1].split()[19]  # field 22, counted after the command name


def _running(pid: int, started: str) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # someone else's process: alive
    return not started or _started(pid) in ("", started)


def make_run_folder() -> Path:
    """A new private run folder, after removing those whose launchers were killed."""
    clean_abandoned()
    folder = Path(tempfile.mkdtemp(prefix=PREFIX))
    (folder / OWNER_FILE).write_text(f"{os.getpid()} {_started(os.getpid())}")
    return folder


def close_run_folder(folder: Path, keep_logs: bool) -> None:
    """The run is over: its folder goes, or only its secrets and owner mark where its logs are kept."""
    if keep_logs:
        shutil.rmtree(folder / SECRETS, ignore_errors=True)
        (folder / OWNER_FILE).unlink(missing_ok=True)
    else:
        shutil.rmtree(folder, ignore_errors=True)


def clean_abandoned(temporary: Path | None = None) -> list[Path]:
    """Remove this user's run folders whose launcher is gone without cleaning up; returns them."""
    removed = []
    for folder in Path(temporary or tempfile.gettempdir()).glob(f"{PREFIX}*"):
        try:
            if folder.stat().st_uid != os.getuid():
                continue
            pid, _, started = (folder / OWNER_FILE).read_text().partition(" ")
            alive = _running(int(pid), started.strip())
        except (OSError, ValueError):
            continue  # no owner mark: kept logs, or not a run folder of ours
        if not alive:
            shutil.rmtree(folder, ignore_errors=True)
            removed.append(folder)
    return removed
