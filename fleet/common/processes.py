"""Processes, the one way: starting, signalling and stopping children, and what every node does the same way.

Parents (`fleet run`'s launcher, the env's distributed arms, the benchmarks) start each
child as a `ChildProcess` in its own process group with its output in a log file, and
stop them with `stop_children` (SIGTERM, a grace period, then SIGKILL; every child
reaped). Children (the nodes) open with `node_arguments`: a `StopFlag` set by
SIGTERM/SIGINT and by the parent's death (a node must never outlive its launcher, even
one killed with SIGKILL: on Linux the kernel sends SIGTERM when the parent dies, via
prctl PR_SET_PDEATHSIG; elsewhere `should_stop` notices the parent change within one
loop), and the scene, or one line naming the file, field and reason.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from scenes.schema import Scene

PR_SET_PDEATHSIG = 1
PR_SET_CHILD_SUBREAPER = 36
PR_SET_NAME = 15
PARENT_ENV = "CLAWFLEET_PARENT_PID"  # set for every child a `ChildProcess` starts: the pid that started it


def _prctl(option: int, value: int | bytes) -> None:
    """Linux's prctl for this process (nothing elsewhere, or where it is refused)."""
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL(None, use_errno=True).prctl(option, value, 0, 0, 0)
        except (OSError, AttributeError):
            pass


def die_with_parent(signum: int = signal.SIGTERM) -> None:
    """Ask Linux to send this process `signum` when its parent dies (nothing elsewhere): no orphan outlives a
    killed parent, and a SIGTERM handler still gets to stop what this process started."""
    _prctl(PR_SET_PDEATHSIG, signum)


def adopt_orphans(adopt: bool = True) -> None:
    """Be the child subreaper (Linux) or stop being it: a process started under this one whose parent dies is
    re-parented here, so it can be stopped and reaped here rather than left to an init that may never reap it."""
    _prctl(PR_SET_CHILD_SUBREAPER, int(adopt))


def name_this_process(name: str) -> None:
    """The name `top`, `ps -o comm` and `pgrep` show (Linux keeps 15 bytes): a node forked from another process is
    named for its own module, not the command that started the process it was forked from."""
    _prctl(PR_SET_NAME, name.encode()[:15])


class StopFlag:
    """Set by SIGTERM or SIGINT (and by the parent's death); loops poll `should_stop`."""

    def __init__(self, watch_parent: bool = True) -> None:
        self.reason = ""
        # the parent that started us (a launcher says who, so a parent that died before we got here is noticed too)
        started_by = os.environ.pop(PARENT_ENV, "")
        self._parent = (int(started_by) if started_by.isdigit() else os.getppid()) if watch_parent else None
        for sig in (signal.SIGTERM, signal.SIGINT):
            signal.signal(sig, self._on_signal)
        if watch_parent:
            die_with_parent()

    def _on_signal(self, signum: int, _frame: object) -> None:
        self.reason = signal.Signals(signum).name

    def should_stop(self) -> bool:
        if not self.reason and self._parent is not None and os.getppid() != self._parent:
            self.reason = "parent exited"
        return bool(self.reason)


def add_scene_arguments(parser: argparse.ArgumentParser, run_required: bool = True) -> None:
    """The scene and run flags every node takes."""
    parser.add_argument("--scene", default="assembly_line", help="bundled scene name or scene file")
    parser.add_argument("--arms", type=int, default=None, help="arm count for scenes with an arm row")
    parser.add_argument("--run", required=run_required, help="run id: keeps several lines on one Zenoh network apart")
    parser.add_argument(
        "--seed", type=int, default=None, help="the run's seed (the scene's by default): arrivals and randomised values"
    )
    parser.add_argument(
        "--perception",
        choices=("truth", "cameras"),
        default="truth",
        help="where the line's parts come from: the sim's truth, or what perception sees through the cameras",
    )


def load_node_scene(args: argparse.Namespace, prog: str) -> Scene | None:
    """The node's scene, or None after printing one line naming the file, field and reason."""
    from fleet.common.scene_loading import (
        load_checked_scene,  # here: the launcher starts its node factory before scenes
    )
    from scenes.loader import SceneError

    try:
        return load_checked_scene(args.scene, arms=args.arms, seed=getattr(args, "seed", None))
    except SceneError as exc:
        print(f"{prog}: {exc}", file=sys.stderr)
        return None


def node_arguments(
    parser: argparse.ArgumentParser, argv: list[str] | None, prog: str
) -> tuple[argparse.Namespace, StopFlag, Scene] | None:
    """A scene node's opening: its flags parsed, its stop flag set up, its scene loaded (None after one error line)."""
    args = parser.parse_args(argv)
    stop = StopFlag()
    scene = load_node_scene(args, prog)
    return None if scene is None else (args, stop, scene)


def run_on_idle_cpu(idle: bool = True, pid: int = 0) -> bool:
    """A thread on CPU time nothing else wants (SCHED_IDLE, Linux), or back to a normal share; `pid` 0 is the
    calling thread, else a process's main thread (threads it starts after inherit it). Whether it is so now:
    elsewhere, or where the OS refuses (leaving SCHED_IDLE needs the privilege to raise priority), it stays as it is."""
    policy = getattr(os, "SCHED_IDLE" if idle else "SCHED_OTHER", None)
    if policy is None:
        return False
    try:
        if os.sched_getscheduler(pid) != policy:
            os.sched_setscheduler(pid, policy, os.sched_param(0))
    except OSError:
        return False
    return True


@dataclass
class ChildProcess:
    """One child: started in its own process group (a Ctrl-C reaches only the parent), output to `log`."""

    argv: list[str]
    log: Path
    proc: subprocess.Popen | None = None  # or the factory's `ForkedProc`, which answers the same calls
    idle: bool = False  # runs on idle CPU time only, from its first instruction (its imports included)
    factory: object | None = None  # a `fleet.run.node_factory.NodeFactory`: forked from it where the command allows

    def start(self) -> ChildProcess:
        if self.factory is not None and self.factory.can_fork(self.argv):
            self.proc = self.factory.spawn(self.argv, self.log, self.idle)
            return self
        with open(self.log, "ab") as log:
            self.proc = subprocess.Popen(
                self.argv,
                stdout=log,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                start_new_session=True,
                env=os.environ | {PARENT_ENV: str(os.getpid())},
            )
        if self.idle:
            run_on_idle_cpu(pid=self.proc.pid)
        return self

    def poll(self) -> int | None:
        return None if self.proc is None else self.proc.poll()

    @property
    def alive(self) -> bool:
        return self.proc is not None and self.proc.poll() is None

    @property
    def pid(self) -> int | None:
        return self.proc.pid if self.proc is not None else None

    def signal(self, sig: int) -> None:
        """Signal the child's whole process group (if it still runs)."""
        if self.alive:
            try:
                os.killpg(self.proc.pid, sig)
            except ProcessLookupError:
                pass

    def wait(self, timeout: float | None = None) -> int:
        """Reap the child (its exit code)."""
        return self.proc.wait(timeout=timeout)

    def kill(self) -> None:
        """SIGKILL the group and reap the child."""
        if self.proc is not None:
            self.signal(signal.SIGKILL)
            self.proc.wait(timeout=5)

    def log_tail(self, lines: int = 3) -> str:
        """The last lines of its output, joined on one line (for one-line error messages)."""
        try:
            text = self.log.read_text(errors="replace").strip().splitlines()
        except OSError:
            return ""
        return " | ".join(line.strip() for line in text[-lines:])


def stop_children(children: Iterable[ChildProcess], grace_s: float = 1.5) -> None:
    """SIGTERM every child (in the given order), SIGKILL what is left after `grace_s`, reap them all."""
    children = [c for c in children if c.proc is not None]
    for c in children:
        c.signal(signal.SIGTERM)
    deadline = time.monotonic() + grace_s
    while any(c.alive for c in children) and time.monotonic() < deadline:
        time.sleep(0.01)
    for c in children:
        if c.alive:
            c.signal(signal.SIGKILL)
        c.proc.wait(timeout=5)


def write_text_atomically(path: str, text: str) -> None:
    """Write a file so that a reader never sees half of it."""
    target = Path(path)
    tmp = target.with_suffix(target.suffix + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, target)


def read_when_written(path: str | Path, timeout_s: float, give_up: Callable[[], bool] = lambda: False) -> str | None:
    """The text another process writes to `path` (with `write_text_atomically`), once it is there; None when it
    is not within `timeout_s`, or `give_up()` says to stop waiting."""
    target = Path(path)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline and not give_up():
        if target.is_file():
            return target.read_text().strip()
        time.sleep(0.02)
    return None


def write_node_report(path: str | None, report: dict) -> None:
    """Write a node's end-of-run figures as JSON."""
    if path:
        write_text_atomically(path, json.dumps(report, indent=1, sort_keys=True))
