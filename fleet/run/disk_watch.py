"""Room on disk for a run: the run folder (its nodes' logs, the sim's spool, the router's log) and the recording's
folder. A node that finds its disk full crashes mid-write (Zenoh panics on a log line it cannot print), so the
launcher keeps a reserve: a run does not start without it, and stops cleanly when it runs short, with room left for
every node to write its report and the recorder its file."""

from __future__ import annotations

import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

MIN_FREE_BYTES = 16 * 2**20  # the reserve: reports, the spool's end and the recording's index fit in far less
CHECK_EVERY_S = 0.25  # wall seconds between looks (a line writes well under a MiB in that time)


@dataclass
class DiskWatch:
    """The folders a run writes to, by what they are to the user (`the temporary folder`, `the recording's
    folder`)."""

    folders: dict[str, Path]
    min_free_bytes: int = MIN_FREE_BYTES
    _looked_at: float = field(default=0.0, repr=False)

    def short(self) -> str:
        """Why a folder has too little room ("" where every one has the reserve)."""
        for what, folder in self.folders.items():
            try:
                free = shutil.disk_usage(folder).free
            except OSError:
                continue  # not made yet, or gone: whoever writes there says so
            if free < self.min_free_bytes:
                return (
                    f"{what} ({folder}) has {free / 2**20:.1f} MiB free, under the "
                    f"{self.min_free_bytes / 2**20:.0f} MiB a run keeps in reserve"
                )
        return ""

    def short_now(self) -> str:
        """`short()`, looked at no more often than every `CHECK_EVERY_S`."""
        if time.monotonic() - self._looked_at < CHECK_EVERY_S:
            return ""
        self._looked_at = time.monotonic()
        return self.short()


def run_disks(run_folder: Path | None, record: str | None) -> DiskWatch:
    """The folders a run writes to: its run folder (the temporary folder, before it is made) and its recording's."""
    recording = {"the recording's folder": Path(record).resolve().parent} if record else {}
    return DiskWatch({"the temporary folder": run_folder or Path(tempfile.gettempdir())} | recording)


def room_problem(record: str | None) -> str:
    """Why a run could not start for room on disk ("": it can), said before anything starts."""
    short = run_disks(None, record).short()
    return f"{short}: free some room, or point TMPDIR (or --record) at a folder with room" if short else ""
