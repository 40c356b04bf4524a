"""Real-time scheduling for a node's process (`fleet run --rt`): SCHED_FIFO where the OS allows it, one warning
line and normal priority where it does not."""

from __future__ import annotations

import os
import sys


def request_realtime_priority(prog: str) -> str:
    """SCHED_FIFO at a middle priority for this process where the OS allows it; what it runs at (one warning line
    where it was refused)."""
    try:
        priority = (os.sched_get_priority_min(os.SCHED_FIFO) + os.sched_get_priority_max(os.SCHED_FIFO)) // 2
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (AttributeError, PermissionError, OSError) as exc:
        print(f"{prog}: warning: real-time priority refused ({exc}); running at normal priority", file=sys.stderr)
        return f"normal (SCHED_FIFO refused: {exc})"
    return f"SCHED_FIFO {priority}"
