"""Child processes as the launcher starts them: a recorder-like child on idle CPU time from its first
instruction, and a thread going back to a normal share once the line it waited on is quiet."""

import os
import sys
import threading
from pathlib import Path

import pytest

from fleet.common.processes import ChildProcess, run_on_idle_cpu

pytestmark = pytest.mark.skipif(not hasattr(os, "SCHED_IDLE"), reason="SCHED_IDLE is Linux's")


def child_policy(tmp_path: Path, idle: bool) -> int:
    out = tmp_path / f"policy_{idle}.txt"
    script = f"import os, time; time.sleep(0.3); open({str(out)!r}, 'w').write(str(os.sched_getscheduler(0)))"
    child = ChildProcess([sys.executable, "-c", script], tmp_path / "child.log", idle=idle).start()
    assert child.wait(timeout=10) == 0, child.log_tail()
    return int(out.read_text())


def test_an_idle_child_runs_on_idle_cpu_time_and_a_plain_one_does_not(tmp_path):
    assert child_policy(tmp_path, idle=True) == os.SCHED_IDLE
    assert child_policy(tmp_path, idle=False) == os.SCHED_OTHER


def test_a_thread_goes_idle_and_back_without_touching_the_others():
    seen = []

    def run():
        run_on_idle_cpu(True)
        seen.append(os.sched_getscheduler(0))
        run_on_idle_cpu(False)
        seen.append(os.sched_getscheduler(0))

    thread = threading.Thread(target=run)
    thread.start()
    thread.join()
    if os.geteuid() == 0:  # leaving SCHED_IDLE needs the privilege (or RLIMIT_NICE) to raise priority
        assert seen == [os.SCHED_IDLE, os.SCHED_OTHER]
    else:
        assert seen[0] == os.SCHED_IDLE
    assert os.sched_getscheduler(0) == os.SCHED_OTHER, "only the calling thread changes"
