"""The node factory: nodes forked from one process that imported once, each in its own process group with its
output in its log, their exit codes reported, none outliving the factory or the launcher that started it."""

import os
import signal
import subprocess
import sys
import textwrap
import time
from concurrent.futures import ThreadPoolExecutor

import pytest

from fleet.run.launcher import Launcher, RunOptions
from fleet.run.node_factory import FactoryError, NodeFactory, forkable

pytestmark = pytest.mark.slow  # whole runs, processes or a browser: `-m "not slow"` leaves them out

CHILD = "tests.fleet.run.factory_child"


def command(*args: str) -> list[str]:
    return [sys.executable, "-m", CHILD, *args]


def gone(pid: int, within_s: float = 5.0) -> bool:
    deadline = time.monotonic() + within_s
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.05)
    return False


def fields(log) -> dict[str, str]:
    return dict(item.split("=", 1) for item in log.read_text().split())


def test_only_this_python_running_a_module_is_forked():
    assert forkable(command("exit", "3")) == (CHILD, ["exit", "3"])
    assert forkable(["ip", "netns", "exec", "sim", sys.executable, "-m", CHILD]) is None
    assert forkable(["/bin/true"]) is None


def test_a_forked_node_has_its_own_group_its_log_and_its_exit_code(tmp_path):
    with NodeFactory(tmp_path / "factory.log", preload=()) as factory:
        proc = factory.spawn(command("exit", "3"), tmp_path / "node.log")
        assert proc.wait(timeout=30) == 3
        said = fields(tmp_path / "node.log")
        assert said["pid"] == str(proc.pid) and said["pgid"] == str(proc.pid), "its own process group"
        assert said["ppid"] == said["parent_env"] == str(factory.proc.pid), "it dies with the factory"
        assert said["idle"] == "False" and said["comm"] == "factory_child", "named for its module (top, ps -o comm)"
        idle = factory.spawn(command("exit", "0"), tmp_path / "idle.log", idle=True)
        assert idle.wait(timeout=30) == 0 and fields(tmp_path / "idle.log")["idle"] == "True"
        crashed = factory.spawn(command("raise"), tmp_path / "crash.log")
        assert crashed.wait(timeout=30) == 1 and "a node that crashed" in (tmp_path / "crash.log").read_text()


def test_a_signalled_node_reads_as_popen_would_and_closing_the_factory_leaves_nothing(tmp_path):
    factory = NodeFactory(tmp_path / "factory.log", preload=())
    killed = factory.spawn(command("sleep", "60"), tmp_path / "a.log")
    left = factory.spawn(command("sleep", "60"), tmp_path / "b.log")
    time.sleep(0.5)
    os.killpg(killed.pid, signal.SIGTERM)
    assert killed.wait(timeout=10) == -signal.SIGTERM
    with pytest.raises(subprocess.TimeoutExpired):
        left.wait(timeout=0.2)
    factory.close()
    assert gone(left.pid) and gone(factory.proc.pid)


def test_nodes_asked_for_from_many_threads_at_once_each_get_their_own_process(tmp_path):
    """Lines run from threads share a kept factory: each spawn's answer must be its own node, not a neighbour's."""
    with NodeFactory(tmp_path / "factory.log", preload=()) as factory, ThreadPoolExecutor(8) as pool:
        spawned = list(pool.map(lambda k: factory.spawn(command("exit", str(k)), tmp_path / f"{k}.log"), range(24)))
        assert [proc.wait(timeout=30) for proc in spawned] == list(range(24))
        assert all(fields(tmp_path / f"{k}.log")["pid"] == str(proc.pid) for k, proc in enumerate(spawned))


def test_a_module_that_cannot_be_imported_is_one_line(tmp_path):
    with NodeFactory(tmp_path / "factory.log", preload=()) as factory:
        with pytest.raises(FactoryError, match="cannot import no_such_module_here"):
            factory.spawn([sys.executable, "-m", "no_such_module_here"], tmp_path / "x.log")


def test_a_killed_launcher_takes_the_factory_and_its_nodes_with_it(tmp_path):
    launcher = textwrap.dedent(f"""
        import sys, time
        from pathlib import Path
        from fleet.run.node_factory import NodeFactory
        factory = NodeFactory(Path({str(tmp_path)!r}) / "factory.log", preload=())
        node = factory.spawn([sys.executable, "-m", {CHILD!r}, "sleep", "60"], Path({str(tmp_path)!r}) / "node.log")
        print(factory.proc.pid, node.pid, flush=True)
        time.sleep(60)
    """)
    proc = subprocess.Popen([sys.executable, "-c", launcher], stdout=subprocess.PIPE, text=True)
    factory_pid, node_pid = map(int, proc.stdout.readline().split())
    proc.kill()
    proc.wait()
    assert gone(factory_pid) and gone(node_pid)


def test_a_run_of_forked_nodes_is_the_run_of_execd_ones():
    summaries = {}
    for fork in (True, False):
        with Launcher(
            RunOptions(scene="sorting_line", arms=2, duration_s=15.0, seed=1, fork_nodes=fork),
            on_message=lambda _t: None,
        ) as run:
            summaries[fork] = run.run()
        for p in summaries[fork]["processes"]:
            assert gone(p["pid"]), p
    forked, execd = summaries[True], summaries[False]
    assert forked["status"] == execd["status"] == "ok"
    for key in (
        "parts_spawned",
        "parts_completed",
        "parts_missed",
        "parts_failed",
        "inter_arm_contacts",
        "grants_given",
        "goal_results",
        "min_separation_m",
    ):
        assert forked[key] == execd[key], key
