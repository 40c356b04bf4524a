"""A run watched while it goes: nodes that crash or hang restarted (or the run ended with one clear line), respawn
requests on the bus answered, the monitor kept up."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

import zenoh

from fleet.bus.codec import Decoder, DropCounter, encode
from fleet.bus.keys import Keys
from fleet.bus.message_checks import progress_problem, sim_status_problem
from fleet.bus.messages import Progress, RespawnRequest, Roster, SimStatus
from fleet.bus.session import Inbox
from fleet.run.disk_watch import DiskWatch
from fleet.run.log_relay import LogRelay
from fleet.run.node_factory import NodeFactory
from fleet.run.run_node import (
    MAX_COORDINATOR_STARTS,
    Node,
    node_of,
    read_report,
    server_url_file,
)
from fleet.run.run_options import RunOptions
from scenes.schema import Scene

SERVERS = {
    "monitor": "the monitor",
    "rosbridge": "the rosbridge server",
    "ros2": "the ROS 2 publisher",
    "foxglove": "the Foxglove server",
}
CANNOT_START = 2  # a node's exit code for input it cannot start from (arguments, scene, snapshot): no respawn helps
ROSTER_PERIOD_S = 1.0  # the roster is said again this often (wall), for whoever joined since


class Supervision:
    """A run watched while it goes (`watch`): what the line says on the bus (progress, the sim's status, respawn
    requests), its nodes restarted or the run ended, its servers' addresses said. It is handed the run's options,
    scene, folder and disks, the launcher's list of nodes (filled as they start), its drop counter, what to call with
    messages and progress, and `stopped`: why the launcher was told to stop ("" while it was not). What it heard is
    the summary's where a node died (`last_progress`, `last_sim_time_s`)."""

    def __init__(
        self,
        options: RunOptions,
        scene: Scene,
        run_dir: Path,
        disk: DiskWatch,
        nodes: list[Node],
        drops: DropCounter,
        on_message: Callable[[str], None],
        on_progress: Callable[[Progress], None] | None,
        stopped: Callable[[], str],
    ) -> None:
        self.options, self.scene, self.dir, self.disk, self.nodes = options, scene, run_dir, disk, nodes
        self.drops, self.on_message, self.on_progress, self.stopped = drops, on_message, on_progress, stopped
        self.factory: NodeFactory | None = None
        self.server_urls: dict[str, str] = {}  # role -> where it serves
        self.servers_gone: set[str] = set()
        self.respawn_requests: list[dict] = []
        self.arms_lost: tuple[str, ...] = ()
        self.last_progress: Progress | None = None  # the line's counts as last heard: the summary's if a node died
        self.progress_at: float | None = None  # when the running coordinator last said its progress (None: not yet)
        self.last_sim_time_s = 0.0
        self.respawns = 0
        self._decoders: dict[str, Decoder] = {}
        self._roster_pub: zenoh.Publisher | None = None
        self._roster_at = -1e9

    def watch(self, session: zenoh.Session, keys: Keys, factory: NodeFactory | None) -> str:
        """Watch the line from `session` until it ends (its nodes forked by `factory`, if any); why it ended ("" for a
        clean end)."""
        self.factory = factory
        inbox = Inbox()
        subs = [session.declare_subscriber(k, inbox) for k in (keys.coord("progress"), keys.respawn, keys.sim_status)]
        self._decoders = {
            keys.coord("progress"): Decoder(Progress, self.drops),
            keys.respawn: Decoder(RespawnRequest, self.drops),
            keys.sim_status: Decoder(SimStatus, self.drops),
        }
        self._roster_pub = session.declare_publisher(keys.roster)
        try:
            return self._supervise(inbox)
        finally:
            for sub in subs:
                sub.undeclare()
            self._roster_pub.undeclare()
            self._roster_pub = None

    def say_roster(self, now: bool = False) -> None:
        """Which start of each counted node runs (`Roster`): at once after a restart, else every second. A node's
        incarnation changes only through this, so nobody else's heartbeat or order can claim a new one."""
        if self._roster_pub is None or not (now or time.monotonic() - self._roster_at >= ROSTER_PERIOD_S):
            return
        self._roster_at = time.monotonic()
        counted = [n for n in self.nodes if n.counts_starts]
        self._roster_pub.put(encode(Roster(tuple(n.name for n in counted), tuple(n.starts for n in counted))))

    def _on_bus(self, inbox: Inbox) -> None:
        for key, payload in inbox.drain():
            decoder = self._decoders.get(key)
            msg = decoder.decode(key, payload) if decoder else None
            problem = self._implausible(msg) if msg is not None else ""
            if problem:
                self.drops.drop(key, problem)
            elif isinstance(msg, Progress):
                self.last_progress, self.progress_at = msg, time.monotonic()
                if self.on_progress is not None:
                    self.on_progress(msg)
            elif isinstance(msg, SimStatus):
                for node in self.nodes:  # the line runs: a node restarted from now on takes it over
                    node.restore_args = []
                self.arms_lost = msg.arms_lost
                self.last_sim_time_s = max(self.last_sim_time_s, msg.sim_time_s)
            elif isinstance(msg, RespawnRequest):
                self.respawn_on_request(msg)

    def _implausible(self, msg: object) -> str:
        """Why a decoded progress report or sim status cannot be true of this line ("": it can)."""
        end_s, arms = self.options.duration_s, [a.name for a in self.scene.arms]
        if isinstance(msg, Progress):
            return progress_problem(msg, len(arms), end_s)
        if isinstance(msg, SimStatus):
            return sim_status_problem(msg, arms, self.options.mode, self.scene.control_hz, end_s)
        return ""

    def respawn_on_request(self, request: RespawnRequest) -> bool:
        """Start an arm's controller again if it died or the sim lost it; refuse (with the reason) otherwise."""
        node = next((n for n in self.nodes if n.role == "controller" and n.name == request.arm), None)
        if node is None:
            why = f"no arm {request.arm!r} (arms: {', '.join(a.name for a in self.scene.arms)})"
        elif node.alive and request.arm not in self.arms_lost:
            why = "its controller is alive and heard"
        else:
            why = ""
        self.respawn_requests.append({"arm": request.arm, "source": request.source, "done": not why, "reason": why})
        if why:
            self.on_message(f"respawn of {request.arm} refused: {why}")
            return False
        if node.alive:  # alive but silent: a hung controller is replaced
            node.child.kill()
        self._restart(node)
        self.on_message(f"respawned {request.arm}'s controller (asked by {request.source})")
        return True

    def _check_servers(self) -> None:
        """Say where each serving node (monitor, rosbridge, ROS 2 publisher) serves once it does, and if it exits:
        the line goes on without it."""
        for node in self.nodes:
            if node.role not in SERVERS:
                continue
            url = server_url_file(self.dir, node.role)
            if node.role not in self.server_urls and url.exists():
                self.server_urls[node.role] = url.read_text().strip()
                self.on_message(f"{node.role}: {self.server_urls[node.role]}")
            if node.poll() is not None and node.role not in self.servers_gone:
                self.servers_gone.add(node.role)
                tail = node.log_tail() or "no output"
                self.on_message(f"{SERVERS[node.role]} exited (exit {node.exit_code}): {tail}; the line goes on")

    def _supervise(self, inbox: Inbox) -> str:
        sim, coordinator = node_of(self.nodes, "sim"), node_of(self.nodes, "coordinator")
        said = LogRelay(coordinator.log, ("allocator ",))  # a plug-in's faults, said on the user's terminal
        while not self.stopped():
            self.say_roster()
            self._on_bus(inbox)
            self._check_servers()
            for line in said.new_lines():
                self.on_message(line)
            if short := self.disk.short_now():  # stopped while every node can still write its report
                return f"{short}: the line stopped at {self.last_sim_time_s:.1f} s of sim time; logs in {self.dir}"
            # every node's state read before the factory's: nodes it forked die with it, and a death seen first must
            # not be blamed on the node
            code, coordinator_code = sim.poll(), coordinator.poll()
            gone = [n for n in self.nodes if n.role == "controller" and n.poll() is not None]
            if self.factory is not None and (died := self.factory.died):
                return f"{died}; logs in {self.dir}"
            if code is not None:
                return self._sim_ended(sim, code)
            if unstarted := next((n for n in [coordinator, *gone] if n.exit_code == CANNOT_START), None):
                tail = unstarted.log_tail() or "no output"
                return f"{unstarted.name} could not start (exit {CANNOT_START}): {tail}; logs in {self.dir}"
            if coordinator_code is None and self._hung(coordinator):
                self.on_message(f"the coordinator said nothing for {self.options.hung_after_s:g} s; replacing it")
                coordinator.child.kill()
                coordinator_code = coordinator.poll()
            if coordinator_code is not None:
                if not (self.options.respawn and coordinator.starts < MAX_COORDINATOR_STARTS):
                    tail = coordinator.log_tail() or "no output"
                    return f"the coordinator crashed (exit {coordinator_code}): {tail}; logs in {self.dir}"
                self.on_message(
                    f"the coordinator crashed (exit {coordinator_code}); starting another to take over the line"
                )
                self._restart(coordinator)
            if self.options.respawn:
                for node in gone:
                    self._restart(node)
            time.sleep(0.02)
        return ""

    def unreachable(self, why: str) -> str:
        """Why the launcher could not reach the line's bus: the sim's own line where it ended (waited for briefly)."""
        sim = node_of(self.nodes, "sim")
        deadline = time.monotonic() + 3.0
        while sim.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        code = sim.poll()
        if code is not None:
            return self._sim_ended(sim, code) or f"the sim server ended before the run began; logs in {self.dir}"
        return f"the launcher could not reach the line's bus: {why.split(' at ')[0]}; logs in {self.dir}"

    def _sim_ended(self, sim: Node, code: int) -> str:
        """Why the run ends with the sim ("" for a clean end)."""
        if code == 0 and read_report(sim.report).get("stopped_by", "").startswith("the coordinator did not answer"):
            return f"the sim stopped: the coordinator did not answer in the lockstep timeout; logs in {self.dir}"
        if code == 0:
            return ""
        if code == CANNOT_START:
            return f"the sim server could not start (exit {code}): {sim.log_tail() or 'no output'}; logs in {self.dir}"
        return f"the sim server crashed (exit {code}): {sim.log_tail() or 'no output'}; logs in {self.dir}"

    def _hung(self, coordinator: Node) -> bool:
        """With `respawn`: the coordinator is alive but has not said its progress for `hung_after_s` since it
        first did (one still starting, computing the line's capacity or taking over, has said nothing yet)."""
        return (
            self.options.respawn
            and coordinator.alive
            and self.progress_at is not None
            and time.monotonic() - self.progress_at > self.options.hung_after_s
            and coordinator.starts < MAX_COORDINATOR_STARTS
        )

    def _restart(self, node: Node) -> None:
        """Start a dead node again, keeping the record of the one that died."""
        node.history.append(node.record())
        if node.role == "coordinator":
            self.progress_at = None
        node.start()
        self.say_roster(now=True)
        self.respawns += 1
