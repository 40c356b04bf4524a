"""A node factory: one child process that imports the node modules once and forks every node of a run from
itself, so that a run pays Python's start-up and its imports (NumPy, SciPy, Pinocchio, SAPIEN, Zenoh, pydantic:
0.6-0.9 s of CPU a process) once instead of once per node.

The launcher starts it (`NodeFactory`) and asks it for each node (`spawn`): module, arguments, log file, idle or
not. The factory forks; the child makes its own process group and session, sends its output to the log,
forgets the factory's signal handlers and calls the module's `main(args)`, then leaves with its exit code. The
factory reaps its children and tells the launcher each exit code; the launcher signals the children directly
(they are in their own process groups, as exec'd nodes are). Safe to fork because the factory never opens a
Zenoh session or a SAPIEN scene (its only threads are the BLAS pools, which OpenBLAS closes around a fork).
The factory dies with the launcher (SIGTERM on the parent's death), and each node with the factory, so no node
outlives a killed launcher; when the launcher closes the factory's input it SIGKILLs what is left and exits.

    python -m fleet.run.node_factory fleet.nodes.sim_server fleet.nodes.arm_controller   # modules to import first
"""

from __future__ import annotations

import importlib
import json
import os
import select
import signal
import subprocess
import sys
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from fleet.common.processes import (
    PARENT_ENV,
    adopt_orphans,
    die_with_parent,
    name_this_process,
    run_on_idle_cpu,
)

NODE_MODULES = (
    "fleet.nodes.sim_server",
    "fleet.nodes.coordinator_node",
    "fleet.nodes.arm_controller",
    "fleet.nodes.recorder_node",
)
SPAWN_TIMEOUT_S = 60.0  # the factory imports a module the first time a node of it is asked for
REAP_EVERY_S = 0.02


def forkable(argv: list[str]) -> tuple[str, list[str]] | None:
    """(module, args) of a command the factory can start: `<this python> -m <module> args...` (not one that starts
    in a network namespace, nor another program)."""
    if len(argv) >= 3 and argv[0] == sys.executable and argv[1] == "-m":
        return argv[2], argv[3:]
    return None


@dataclass
class ForkedProc:
    """A node the factory forked, with `subprocess.Popen`'s `pid`, `poll`, `wait` and `returncode`; `exit_code` asks
    the factory for a pid's (None while it runs)."""

    pid: int
    exit_code: Callable[[int], int | None]
    returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            self.returncode = self.exit_code(self.pid)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = None if timeout is None else time.monotonic() + timeout
        while self.poll() is None:
            if deadline is not None and time.monotonic() > deadline:
                raise subprocess.TimeoutExpired(f"pid {self.pid}", timeout)
            time.sleep(0.005)
        return self.returncode


_FACTORIES_OPEN = [0]


def adopting(change: int) -> None:
    """This process adopts orphans while it has a factory open or a run on a kept one (and only then: it reaps only
    its nodes; a subreaper for longer would keep, unreaped, whatever else it started that outlived its parent)."""
    before = _FACTORIES_OPEN[0]
    _FACTORIES_OPEN[0] = max(0, before + change)
    if (before == 0) != (_FACTORIES_OPEN[0] == 0):
        adopt_orphans(_FACTORIES_OPEN[0] > 0)


def _stop_orphan(pid: int) -> int:
    """A node whose factory died (re-parented to the launcher, `adopt_orphans`): killed if it still runs, and
    reaped; its exit code reads as killed."""
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    try:
        os.waitpid(pid, 0)
    except ChildProcessError:
        pass  # not ours to reap (no subreaper where Linux has none): init reaps it
    return -signal.SIGKILL


class FactoryError(RuntimeError):
    """The factory did not start a node (it died, or did not answer); one line for the user."""


class NodeFactory:
    """The launcher's side: `spawn(argv, log, idle)` a node, `close()` at the end (use in a `with` block)."""

    def __init__(self, log: Path | None, preload: tuple[str, ...] = NODE_MODULES, adopt: bool = True) -> None:
        """`log`: where the factory's own output goes (None: nowhere; each node has its own log either way).
        `adopt`: be the subreaper while it is open (False: a kept factory, whose runs adopt while they run)."""
        self.log, self.adopt = log, adopt
        if adopt:
            adopting(+1)  # the nodes outlive a factory killed under them: they come here to be stopped and reaped
        with open(log if log is not None else os.devnull, "ab") as out:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "fleet.run.node_factory", *preload],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=out,
                start_new_session=True,
                env=os.environ | {PARENT_ENV: str(os.getpid())},
            )
        self._exits: dict[int, int] = {}
        self._replies: list[dict] = []
        self._heard = threading.Condition()
        self._one_spawn = threading.Lock()
        self._closing = False
        self._spawned = False  # asked to start a node at least once
        self._reader = threading.Thread(target=self._read, name="node-factory", daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.proc.stdout:
            message = json.loads(line)
            with self._heard:
                if "exit" in message:
                    self._exits[message["exit"]] = message["code"]
                else:
                    # a pid used again (32768 of them here): not the old node's exit
                    self._exits.pop(message.get("pid"), None)
                    self._replies.append(message)
                self._heard.notify_all()
        with self._heard:  # the factory is gone: so are its children (they die with it)
            self._replies.append({"error": f"the node factory exited (exit {self.proc.wait()})"})
            self._heard.notify_all()

    def spawn(self, argv: list[str], log: Path, idle: bool = False) -> ForkedProc:
        """Start the node `argv` (a `forkable` command) with its output in `log`; its process (running already)."""
        module, args = forkable(argv) or (None, None)
        if module is None:
            raise ValueError(f"not a node the factory can fork: {' '.join(argv)}")
        request = {"module": module, "args": args, "log": str(log), "idle": idle}
        self._spawned = True
        with self._one_spawn, self._heard:  # one request in flight: the next reply is its own
            try:
                self.proc.stdin.write(json.dumps(request).encode() + b"\n")
                self.proc.stdin.flush()
            except (BrokenPipeError, ValueError):
                raise FactoryError(f"the node factory is gone{self._see}") from None
            if not self._heard.wait_for(lambda: self._replies, SPAWN_TIMEOUT_S):
                raise FactoryError(f"the node factory did not start {module} within {SPAWN_TIMEOUT_S:.0f} s{self._see}")
            reply = self._replies.pop(0)
        if "error" in reply:
            raise FactoryError(f"{reply['error']}{self._see}")
        return ForkedProc(reply["pid"], self.exit_code)

    @property
    def _see(self) -> str:
        return f"; see {self.log}" if self.log is not None else ""

    @staticmethod
    def can_fork(argv: list[str]) -> bool:
        return forkable(argv) is not None

    def exit_code(self, pid: int) -> int | None:
        """A forked node's exit code (None while it runs); a node of a factory that died died with it (SIGKILL)."""
        with self._heard:
            code = self._exits.get(pid)
        if code is None and self.died is not None:
            code = self._exits[pid] = _stop_orphan(pid)
        return code

    @property
    def died(self) -> str | None:
        """Why the factory is gone before `close()` (its nodes died with it), or None while it serves."""
        if self._closing or self.proc.poll() is None or self._reader.is_alive():
            return None
        return f"the node factory exited (exit {self.proc.returncode}); every node it forked died with it"

    def close(self) -> None:
        """Close the factory's input: it SIGKILLs any node still running, reaps them and exits."""
        if self._closing:
            return
        self._closing = True
        if not self._spawned and self.proc.poll() is None:  # nothing of it to reap (a refused `fleet run`): do not
            self.proc.kill()  # wait for the imports it is still doing to end before it reads that it may go
        if self.proc.stdin and not self.proc.stdin.closed:
            try:
                self.proc.stdin.close()
            except BrokenPipeError:
                pass
        try:
            self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self._reader.join(timeout=1)
        if self.adopt:
            adopting(-1)

    def __enter__(self) -> NodeFactory:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


_KEPT: dict[str, NodeFactory | None] = {"factory": None}


def keep_factory() -> NodeFactory:
    """From now on, this process's runs fork their nodes from one kept factory (a sweep's worker, a test session: a
    program that runs many lines one after another pays the imports once, not once a run, ~2 s each). Returns it,
    started at the first call and replaced when it died (a run that lost its factory fails; the next gets a new
    one). `close_kept_factory` ends it; it dies with this process anyway."""
    kept = _KEPT["factory"]
    if kept is None or kept.proc.poll() is not None:
        if kept is not None:
            kept.close()
        # no log of its own: it outlives every run's folder (each node logs there)
        kept = _KEPT["factory"] = NodeFactory(None, adopt=False)  # each run on it adopts while it runs
    return kept


def kept_factory() -> NodeFactory | None:
    """The kept factory if `keep_factory` was called (a new one if it died), else None (each run starts its own)."""
    return keep_factory() if _KEPT["factory"] is not None else None


def close_kept_factory() -> None:
    """Stop keeping a factory: close it (its nodes, if any still run, are killed)."""
    kept, _KEPT["factory"] = _KEPT["factory"], None
    if kept is not None:
        kept.close()


# --- the factory process ------------------------------------------------------------------------------------
def _become_node(module: str, args: list[str], log: str, idle: bool, factory: int) -> int:
    """In the forked child: its own session, output and signals, then the module's `main(args)`; its exit code."""
    os.setsid()
    out = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, 0)
    os.dup2(out, 1)
    os.dup2(out, 2)
    os.close(out)
    os.close(null)
    for sig in (signal.SIGTERM, signal.SIGINT, signal.SIGCHLD):
        signal.signal(sig, signal.SIG_DFL)
    die_with_parent()  # SIGTERM when the factory dies (and it dies with the launcher)
    if os.getppid() != factory:  # it died before we asked
        return 1
    os.environ[PARENT_ENV] = str(factory)
    name_this_process(module.rsplit(".", 1)[-1])
    if idle:
        run_on_idle_cpu(True)
    try:
        code = importlib.import_module(module).main(args)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
        if isinstance(exc.code, str):
            print(exc.code, file=sys.stderr)
    except BaseException:
        traceback.print_exc()
        code = 1
    return int(code or 0)


def _reap(say, children: set[int]) -> None:
    """Every child that exited, reaped, its exit code said, and forgotten (its pid may be used again)."""
    while True:
        try:
            pid, status = os.waitpid(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return
        children.discard(pid)
        say({"exit": pid, "code": os.waitstatus_to_exitcode(status)})


def _serve(preload: list[str]) -> int:
    die_with_parent()
    signal.signal(signal.SIGTERM, lambda *_: os._exit(0))  # the launcher died: the nodes follow (they die with us)
    requests = sys.stdin.buffer
    replies = sys.stdout.buffer

    def say(message: dict) -> None:
        replies.write(json.dumps(message).encode() + b"\n")
        replies.flush()

    pending = list(preload)  # imported while no node is asked for
    children: set[int] = set()
    while True:
        ready, _, _ = select.select([requests], [], [], 0 if pending else REAP_EVERY_S)
        _reap(say, children)
        if not ready:
            if pending:
                importlib.import_module(pending.pop(0))
            continue
        line = requests.readline()
        if not line:
            break  # the launcher is done: nothing of ours may stay
        request = json.loads(line)
        try:
            importlib.import_module(request["module"])
        except BaseException as exc:  # noqa: BLE001 - one line back to the launcher
            say({"error": f"cannot import {request['module']}: {exc}"})
            continue
        sys.stdout.flush()
        sys.stderr.flush()
        me = os.getpid()
        pid = os.fork()
        if pid == 0:
            code = 1
            try:
                code = _become_node(request["module"], request["args"], request["log"], request["idle"], me)
            finally:
                try:
                    sys.stdout.flush()
                    sys.stderr.flush()
                finally:
                    os._exit(code)
        children.add(pid)
        say({"pid": pid})
    for pid in children:  # only nodes still running: a reaped one's pid may be someone else's by now
        try:
            os.killpg(pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    for pid in children:
        try:
            os.waitpid(pid, 0)
        except ChildProcessError:
            pass
    return 0


if __name__ == "__main__":
    code = _serve(sys.argv[1:])
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)  # no interpreter teardown of SAPIEN, Pinocchio and the BLAS pools (~0.2 s): nothing is left to close
