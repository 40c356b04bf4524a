"""`--rt`: a process asks for SCHED_FIFO and says what it got, the scheduler it then runs at or why it was refused
(in a process of its own: the test's must not run at real-time priority)."""

import os
import subprocess
import sys

ASK = """
import os
from fleet.common.realtime_priority import request_realtime_priority
said = request_realtime_priority("test")
print(said)
print(os.sched_getscheduler(0) == os.SCHED_FIFO)
"""


def test_a_process_asking_for_real_time_priority_says_what_it_runs_at():
    done = subprocess.run([sys.executable, "-c", ASK], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    said, fifo = done.stdout.split("\n")[:2]
    if fifo == "True":
        assert said.startswith("SCHED_FIFO ") and done.stderr == ""
    else:
        assert said.startswith("normal (SCHED_FIFO refused: "), said
        assert done.stderr.startswith("test: warning: real-time priority refused"), done.stderr
    assert os.sched_getscheduler(0) != os.SCHED_FIFO, "the test's own process is left alone"
