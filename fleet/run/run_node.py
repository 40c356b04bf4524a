"""One child process of a run (its role, report file, log and earlier incarnations), and how long a run waits for
each kind of node."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

from fleet.common.processes import ChildProcess

STOP_GRACE_S = 1.5
RECORDER_GRACE_S = 120.0  # a recorder behind the line finishes writing what it heard; killing it would lose the file
RECORDER_START_S = 60.0  # the recorder waits this long for the sim's spool
# with `respawn`, a lockstep sim waits this long for a coordinator (a new one starts)
COORDINATOR_RESPAWN_TIMEOUT_S = 60.0
MAX_COORDINATOR_STARTS = 4  # a coordinator that keeps crashing ends the run
# with `respawn`, a live coordinator silent this long (wall; it says its progress every 0.5 s) is replaced
HUNG_COORDINATOR_S = 10.0


def read_report(path: Path) -> dict:
    """A node's report (JSON), or {} where it wrote none or not a whole one."""
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def server_url_file(folder: Path, role: str) -> Path:
    """Where a serving node (`monitor`, `rosbridge`, `foxglove`) writes its URL in the run's folder once it serves."""
    return folder / f"{role}_url"


def node_of(nodes: list[Node], role: str) -> Node | None:
    """The first node of `role` among `nodes` (the run's only sim, coordinator, monitor...), found by its role, not
    its place in the list; None where the run has none."""
    return next((n for n in nodes if n.role == role), None)


@dataclass
class Node:
    """One child process of the run, with its role, report file and earlier incarnations."""

    role: str
    name: str
    argv: list[str]
    report: Path
    log: Path
    exit_code: int | None = None
    history: list[dict] = field(default_factory=list)  # earlier incarnations (respawned controllers)
    # passes `--incarnation N` (N = 1, 2, ... each start): a controller's goal ids repeat for a seed
    counts_starts: bool = False
    idle: bool = False  # on idle CPU time only (the recorder: the line's own processes come first)
    starts: int = 0
    # given to each start until the line runs (`--from SNAPSHOT`: one restarted while the line is restored restores
    # too); the supervisor drops them then, for a node restarted later takes over the running line
    restore_args: list[str] = field(default_factory=list)
    child: ChildProcess = field(init=False)

    def __post_init__(self) -> None:
        self.child = ChildProcess(self.argv, self.log, idle=self.idle)

    def start(self) -> None:
        self.starts += 1
        counted = ["--incarnation", str(self.starts)] if self.counts_starts else []
        self.child.argv = [*self.argv, *self.restore_args, *counted]
        self.child.start()
        self.exit_code = None

    @property
    def proc(self):
        return self.child.proc

    def poll(self) -> int | None:
        if self.exit_code is None:
            self.exit_code = self.child.poll()
        return self.exit_code

    @property
    def alive(self) -> bool:
        return self.child.proc is not None and self.poll() is None

    def signal(self, sig: int) -> None:
        if self.alive:
            self.child.signal(sig)

    def log_tail(self, lines: int = 3) -> str:
        return self.child.log_tail(lines)

    def record(self) -> dict:
        return {
            "role": self.role,
            "name": self.name,
            "pid": self.proc.pid if self.proc else None,
            "exit_code": self.poll(),
        }
