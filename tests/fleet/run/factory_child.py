"""A node for the node factory's tests: says who it is (pid, group, parent, CPU policy), then sleeps or exits."""

import os
import time


def main(argv: list[str] | None = None) -> int:
    args = argv or []
    print(
        f"pid={os.getpid()} pgid={os.getpgid(0)} ppid={os.getppid()} idle={os.sched_getscheduler(0) == os.SCHED_IDLE} "
        f"parent_env={os.environ.get('CLAWFLEET_PARENT_PID')} comm={open('/proc/self/comm').read().strip()}",
        flush=True,
    )
    if args and args[0] == "sleep":
        time.sleep(float(args[1]))
        return 0
    if args and args[0] == "raise":
        raise RuntimeError("a node that crashed")
    return int(args[1]) if args and args[0] == "exit" else 0
