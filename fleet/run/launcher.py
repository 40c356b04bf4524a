"""`fleet run`: start the sim server, the coordinator and one controller per arm as OS processes, and stop them all.

The sim server listens on a loopback endpoint; every other node connects to it.
Nodes run in their own process groups (a Ctrl-C reaches only the launcher, which
then stops them in order), die with the launcher even if it is killed, and
write their end-of-run figures to JSON files that the launcher merges into one
summary. A dead controller is reported and, with `respawn`, started again; so is a
dead coordinator (the new one takes over the line: `fleet/nodes/coordinator_node.py`), and
meanwhile a lockstep sim holds the line for it. A dead sim server ends the run with one clear
message, the summary's counts from what the launcher last heard.
"""

from __future__ import annotations

import json
import shutil
import signal
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from coordinator.cadence import moves_need_grants
from coordinator.ledger import PIPELINE_DEFAULT
from fleet.bus.bus_config import BusConfigError, BusConfigSet
from fleet.bus.codec import Decoder, DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import Progress, RespawnRequest, SimStatus
from fleet.bus.session import BusEndpoints, Inbox, open_session
from fleet.common.processes import ChildProcess, read_when_written, stop_children, write_text_atomically
from fleet.common.scene_loading import load_scene
from fleet.run.hosts import Hosts, load_hosts
from fleet.run.node_factory import NodeFactory
from scenes.schema import Scene

STOP_GRACE_S = 1.5
RECORDER_GRACE_S = 120.0  # a recorder behind the line finishes writing what it heard; killing it would lose the file
RECORDER_START_S = 60.0  # the recorder waits this long for the sim's spool
COORDINATOR_RESPAWN_TIMEOUT_S = (
    60.0  # with `respawn`, a lockstep sim waits this long for a coordinator (a new one starts)
)
MAX_COORDINATOR_STARTS = 4  # a coordinator that keeps crashing ends the run
HUNG_COORDINATOR_S = (
    10.0  # with `respawn`, a live coordinator silent this long (wall; it says its progress every 0.5 s) is replaced
)


@dataclass(frozen=True)
class RunOptions:
    """What `fleet run` was asked for."""

    scene: str = "assembly_line"
    arms: int | None = None
    duration_s: float = 120.0
    mode: str = "lockstep"
    speed: float = 1.0
    seed: int | None = None
    respawn: bool = False
    realtime_priority: bool = False
    run_id: str = "line"
    listen: str | None = None
    connect: tuple[str, ...] = ()
    zenoh_config: str | None = None
    keep_logs: bool = False
    allocator: str = "optimal"
    pipeline: bool = PIPELINE_DEFAULT  # fixtures take their next part's arm before they are ready (held at the edge)
    monitor: bool = False
    monitor_host: str = "127.0.0.1"
    monitor_port: int = 8080
    record_targets: str | None = None  # the sim saves every tick's drive targets here (benchmarks replay them)
    record: str | None = None  # an MCAP file: the sim spools the bus from before its first client, a recorder writes it
    bus_config: str | None = None  # a `fleet bus-config` directory: the sim a router, each node its own login
    hosts: str | None = None  # a hosts file: the network namespace each node starts in (`fleet/run/hosts.py`)
    fork_nodes: bool = (
        True  # nodes forked from one process that imported once (`fleet/run/node_factory.py`), not exec'd each
    )
    latency_ms: float | None = None  # network faults on every link (None: the scene's)
    jitter_ms: float | None = None
    loss: float | None = None


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
    counts_starts: bool = (
        False  # passes `--incarnation N` (N = 1, 2, ... each start): a controller's goal ids repeat for a seed
    )
    idle: bool = False  # on idle CPU time only (the recorder: the line's own processes come first)
    starts: int = 0
    child: ChildProcess = field(init=False)

    def __post_init__(self) -> None:
        self.child = ChildProcess(self.argv, self.log, idle=self.idle)

    def start(self) -> None:
        self.starts += 1
        if self.counts_starts:
            self.child.argv = [*self.argv, "--incarnation", str(self.starts)]
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


class RunError(RuntimeError):
    """The run could not go on (a node crashed); the message is one line for the user."""


def placement(bus_config: str | None, hosts: str | None, scene: Scene) -> tuple[BusConfigSet | None, Hosts | None]:
    """The bus configs (`fleet bus-config`, written for exactly the scene's arms) and the hosts file of a run, each
    if given; a `BusConfigError` or `HostsFileError` (one line) if one cannot be used."""
    arms = [a.name for a in scene.arms]
    bus = BusConfigSet.load(bus_config) if bus_config else None
    if bus is not None and sorted(bus.arms) != sorted(arms):
        raise BusConfigError(
            f"{bus_config}: written for arms {', '.join(bus.arms)}, the scene has {', '.join(arms)} "
            f"(fleet bus-config --arms {' '.join(arms)} ...)"
        )
    return bus, load_hosts(hosts, ["sim", "coordinator", *arms, "monitor", "recorder"]) if hosts else None


class Launcher:
    """Use as a context manager: `with Launcher(options) as run: summary = run.run()`; leaving stops every node."""

    def __init__(
        self,
        options: RunOptions,
        on_progress: Callable[[Progress], None] | None = None,
        on_message: Callable[[str], None] | None = None,
        factory: NodeFactory | None = None,
    ) -> None:
        """`factory`: a node factory that outlives this run (a sweep's worker keeps one for all its runs); else,
        with `fork_nodes`, the run starts its own and closes it at the end."""
        self.options = options
        self.on_message = on_message or (lambda text: print(text, file=sys.stderr, flush=True))
        self.monitor_url = ""
        self.monitor_gone = False
        self.respawn_requests: list[dict] = []
        self.arms_lost: tuple[str, ...] = ()
        self.last_progress: Progress | None = None  # the line's counts as last heard: the summary's if a node died
        self.progress_at: float | None = None  # when the running coordinator last said its progress (None: not yet)
        self.last_sim_time_s = 0.0
        self.scene = load_scene(options.scene, arms=options.arms, seed=options.seed)
        self.seed = self.scene.seed
        self.bus, self.hosts = placement(options.bus_config, options.hosts, self.scene)
        self.on_progress = on_progress
        self.dir = Path(tempfile.mkdtemp(prefix="clawfleet-run-"))
        self.endpoint = options.listen or ""  # without --listen the sim picks a free loopback port and says which
        self.nodes: list[Node] = []
        self.recorder: Node | None = None  # started before the clients, stopped after the summary
        # forks the nodes; its own is closed after they all stopped
        self.factory = factory if options.fork_nodes else None
        self._own_factory = False
        self.respawns = 0
        self.interrupted = ""
        self.keep_dir = options.keep_logs

    # --- processes ------------------------------------------------------------------
    def _bus_args(self, listen: bool, node: str = "") -> list[str]:
        o = self.options
        if self.bus is not None:  # its config says where it listens or connects, and as whom
            return ["--zenoh-config", self.bus.config_for(node)]
        args = ["--listen", self.endpoint] if listen else (["--connect", self.endpoint] if self.endpoint else [])
        for ep in o.connect:
            args += ["--connect", ep]
        if o.zenoh_config:
            args += ["--zenoh-config", o.zenoh_config]
        return args

    def _here(self, node: str) -> list[str]:
        """How a node's command starts: in its network namespace when the hosts file names one."""
        return [*(self.hosts.prefix(node) if self.hosts else []), sys.executable, "-m"]

    def _node(self, role: str, name: str, module: str, extra: list[str], listen: bool = False) -> Node:
        o = self.options
        node = name if role == "controller" else role
        argv = [
            *self._here(node),
            module,
            "--scene",
            o.scene,
            "--run",
            o.run_id,
            "--seed",
            str(self.seed),
            *self._bus_args(listen, node),
            *extra,
        ]
        if o.arms is not None:
            argv += ["--arms", str(o.arms)]
        report, log = self.dir / f"{name}.json", self.dir / f"{name}.log"
        return Node(role, name, [*argv, "--report", str(report)], report, log)

    def sim_node(self) -> Node:
        o = self.options
        sim_args = ["--duration", str(o.duration_s), "--mode", o.mode, "--speed", str(o.speed), "--coordinator"]
        if not o.listen:
            sim_args += ["--endpoint-file", str(self.dir / "endpoint")]
        if o.record_targets:
            sim_args += ["--record-targets", o.record_targets]
        if o.record:  # what the bus carries, as the sim hears it, for the recorder (no second copy on the wire)
            sim_args += ["--spool", str(self.spool_path)]
        if o.respawn:
            sim_args += ["--coordinator-timeout", str(COORDINATOR_RESPAWN_TIMEOUT_S)]
        for flag, value in (("--latency-ms", o.latency_ms), ("--jitter-ms", o.jitter_ms), ("--loss", o.loss)):
            if value is not None:
                sim_args += [flag, repr(value)]
        return self._node("sim", "sim_server", "fleet.nodes.sim_server", sim_args, listen=bool(o.listen))

    def client_nodes(self) -> list[Node]:
        """The coordinator and one controller per arm, connecting to the sim's endpoint."""
        o = self.options
        nodes = [
            self._node(
                "coordinator",
                "coordinator",
                "fleet.nodes.coordinator_node",
                ["--mode", o.mode, "--allocator", o.allocator, *([] if o.pipeline else ["--no-pipeline"])],
            )
        ]
        nodes[0].counts_starts = True  # `--incarnation N`: from the 2nd start on, it takes over the running line
        for arm in self.scene.arms:
            grants = ["--grants"] if moves_need_grants(self.scene) else []  # a lone arm has nobody to ask about
            extra = ["--arm", arm.name, *grants] + (["--rt"] if o.realtime_priority else [])
            node = self._node("controller", arm.name, "fleet.nodes.arm_controller", extra)
            node.counts_starts = True
            nodes.append(node)
        return nodes

    def monitor_node(self) -> Node:
        """The browser monitor, attached over the bus like any other client (no scene flags: it asks the sim)."""
        o = self.options
        report, log = self.dir / "monitor.json", self.dir / "monitor.log"
        argv = [
            *self._here("monitor"),
            "fleet.nodes.monitor_node",
            "--run",
            o.run_id,
            *self._bus_args(False, "monitor"),
            "--host",
            o.monitor_host,
            "--port",
            str(o.monitor_port),
            "--url-file",
            str(self.dir / "monitor_url"),
            "--report",
            str(report),
        ]
        return Node("monitor", "monitor", argv, report, log)

    @property
    def spool_path(self) -> Path:
        return self.dir / "bus.spool"

    def recorder_node(self) -> Node:
        """The recorder, reading the sim's spool as the sim writes it (`fleet/record/spool.py`); it adds the summary
        found in `summary.json`."""
        o = self.options
        report, log = self.dir / "recorder.json", self.dir / "recorder.log"
        argv = [
            *self._here("recorder"),
            "fleet.nodes.recorder_node",
            "--spool",
            str(self.spool_path),
            "--scene-timeout",
            str(RECORDER_START_S),
            "--out",
            str(o.record),
            "--summary-file",
            str(self.dir / "summary.json"),
            "--report",
            str(report),
            *(["--hold"] if o.mode == "lockstep" else []),
        ]
        return Node("recorder", "recorder", argv, report, log, idle=True)

    def finish_recording(self, summary: dict) -> dict:
        """Hand the recorder the summary and let it finish the file; what it reports."""
        write_text_atomically(str(self.dir / "summary.json"), json.dumps(summary, sort_keys=True))
        stop_children([self.recorder.child], RECORDER_GRACE_S)
        report = self._read(self.recorder)
        if not report:
            self.on_message(
                f"the recorder did not finish {self.options.record}: {self.recorder.log_tail() or 'no output'}"
            )
        return report

    def _start(self, node: Node) -> Node:
        node.child.factory = self.factory
        node.start()
        return node

    def __enter__(self) -> Launcher:
        try:
            if self.options.fork_nodes and self.factory is None:
                self.factory, self._own_factory = NodeFactory(self.dir / "node_factory.log"), True
            sim = self.sim_node()
            self.nodes = [self._start(sim)]
            if self.options.record:  # beside the sim: it waits for the sim's spool while both import
                self.recorder = self._start(self.recorder_node())
            if not self.endpoint or self.bus is not None:  # the sim listens: clients may connect (a client that
                self.endpoint = self._await_endpoint(sim)  # finds no router gives up)
            self.nodes += self.client_nodes()
            if self.options.monitor:
                self.nodes.append(self.monitor_node())
            for node in self.nodes[1:]:
                self._start(node)
        except BaseException:
            self.__exit__()
            raise
        return self

    def _await_endpoint(self, sim: Node, timeout_s: float = 60.0) -> str:
        """The endpoint the sim server listens on, once it has bound it."""
        endpoint = read_when_written(self.dir / "endpoint", timeout_s, give_up=lambda: sim.poll() is not None)
        if endpoint is not None:
            return endpoint
        if sim.poll() is not None:
            self.keep_dir = True
            raise RunError(
                f"the sim server exited while starting (exit {sim.exit_code}): {sim.log_tail() or 'no output'}; logs "
                f"in {self.dir}"
            )
        raise RunError(f"the sim server did not start listening within {timeout_s:.0f} s; logs in {self.dir}")

    def __exit__(self, *exc: object) -> None:
        self.stop_all()
        if self.recorder is not None:
            stop_children([self.recorder.child], RECORDER_GRACE_S)
        if self._own_factory:
            self.factory.close()
        if not self.keep_dir:
            shutil.rmtree(self.dir, ignore_errors=True)

    def stop_all(self) -> None:
        """SIGTERM every node (the sim first, so it writes its figures), SIGKILL what is left after a grace period."""
        stop_children([n.child for n in self.nodes], STOP_GRACE_S)

    # --- the run --------------------------------------------------------------------
    def run(self) -> dict:
        """Run until the sim's duration ends, a node crashes or the launcher is told to stop; then the summary."""
        started = time.monotonic()
        previous = {sig: signal.signal(sig, self._on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
        error = ""
        try:
            mine = (
                BusEndpoints(config_file=self.bus.config_for("launcher"))
                if self.bus
                else BusEndpoints(connect=(self.endpoint,))
            )
            with open_session(mine) as session:
                keys, inbox, drops = Keys(self.options.run_id), Inbox(), DropCounter()
                subs = [
                    session.declare_subscriber(k, inbox)
                    for k in (keys.coord("progress"), keys.respawn, keys.sim_status)
                ]
                self._decoders = {
                    keys.coord("progress"): Decoder(Progress, drops),
                    keys.respawn: Decoder(RespawnRequest, drops),
                    keys.sim_status: Decoder(SimStatus, drops),
                }
                try:
                    error = self._supervise(inbox)
                finally:
                    for sub in subs:
                        sub.undeclare()
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            self.stop_all()
        if error:
            self.keep_dir = True
        summary = self.summary(time.monotonic() - started, error)
        if self.recorder is not None:
            summary["recording"] = self.finish_recording(summary)
            summary["processes"].append(self.recorder.record())
            summary["wall_seconds"] = round(time.monotonic() - started, 3)  # until the file is whole
        return summary

    def _on_signal(self, signum: int, _frame: object) -> None:
        self.interrupted = signal.Signals(signum).name

    def _on_bus(self, inbox: Inbox) -> None:
        for key, payload in inbox.drain():
            decoder = self._decoders.get(key)
            msg = decoder.decode(key, payload) if decoder else None
            if isinstance(msg, Progress):
                self.last_progress, self.progress_at = msg, time.monotonic()
                if self.on_progress is not None:
                    self.on_progress(msg)
            elif isinstance(msg, SimStatus):
                self.arms_lost = msg.arms_lost
                self.last_sim_time_s = max(self.last_sim_time_s, msg.sim_time_s)
            elif isinstance(msg, RespawnRequest):
                self.respawn_on_request(msg)

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

    def _check_monitor(self) -> None:
        monitor = next((n for n in self.nodes if n.role == "monitor"), None)
        if monitor is None:
            return
        if not self.monitor_url and (self.dir / "monitor_url").exists():
            self.monitor_url = (self.dir / "monitor_url").read_text().strip()
            self.on_message(f"monitor: {self.monitor_url}")
        if monitor.poll() is not None and not self.monitor_gone:
            self.monitor_gone = True
            self.on_message(
                f"the monitor exited (exit {monitor.exit_code}): {monitor.log_tail() or 'no output'}; the line goes on"
            )

    def _supervise(self, inbox: Inbox) -> str:
        sim, coordinator = self.nodes[0], self.nodes[1]
        while not self.interrupted:
            self._on_bus(inbox)
            self._check_monitor()
            code = sim.poll()
            if code is not None:
                if code == 0 and self._read(sim).get("stopped_by", "").startswith("the coordinator did not answer"):
                    return (
                        f"the sim stopped: the coordinator did not answer in the lockstep timeout; logs in {self.dir}"
                    )
                return (
                    ""
                    if code == 0
                    else f"the sim server crashed (exit {code}): {sim.log_tail() or 'no output'}; logs in {self.dir}"
                )
            if self._hung(coordinator):
                self.on_message(f"the coordinator said nothing for {HUNG_COORDINATOR_S:.0f} s; replacing it")
                coordinator.child.kill()
            code = coordinator.poll()
            if code is not None:
                if not (self.options.respawn and coordinator.starts < MAX_COORDINATOR_STARTS):
                    tail = coordinator.log_tail() or "no output"
                    return f"the coordinator crashed (exit {code}): {tail}; logs in {self.dir}"
                self.on_message(f"the coordinator crashed (exit {code}); starting another to take over the line")
                self._restart(coordinator)
            for node in self.nodes[2:]:
                if node.role == "controller" and node.poll() is not None and self.options.respawn:
                    self._restart(node)
            time.sleep(0.02)
        return ""

    def _hung(self, coordinator: Node) -> bool:
        """With `respawn`: the coordinator is alive but has not said its progress for `HUNG_COORDINATOR_S` since it
        first did (one still starting, computing the line's capacity or taking over, has said nothing yet)."""
        return (
            self.options.respawn
            and coordinator.alive
            and self.progress_at is not None
            and time.monotonic() - self.progress_at > HUNG_COORDINATOR_S
            and coordinator.starts < MAX_COORDINATOR_STARTS
        )

    def _restart(self, node: Node) -> None:
        """Start a dead node again, keeping the record of the one that died."""
        node.history.append(node.record())
        if node.role == "coordinator":
            self.progress_at = None
        node.start()
        self.respawns += 1

    # --- the summary ----------------------------------------------------------------
    def _read(self, node: Node) -> dict:
        try:
            return json.loads(node.report.read_text())
        except (OSError, ValueError):
            return {}

    @staticmethod
    def _capacity(capacity: dict | None, of_run: dict | None, completed: int, sim_s: float) -> dict:
        """The line's capacity bound (the coordinator's) and how much of it this run achieved; the same against the
        bound of this run's own arrivals (those in time to be finished), which a short run's luck moves."""
        if not capacity:
            return {
                "throughput_bound_per_min": None,
                "bound_fraction": None,
                "bottleneck": None,
                "run_bound_per_min": None,
                "run_bound_fraction": None,
                "parts_finishable": None,
            }
        bound = capacity["throughput_bound_per_min"]
        achieved = completed / (sim_s / 60.0) if sim_s > 0 else 0.0
        busy = capacity["arm_busy_at_bound"] | capacity["station_busy_at_bound"]
        run_bound = of_run["throughput_bound_per_min"] if of_run else None
        return {
            "throughput_bound_per_min": bound,
            "bound_fraction": round(achieved / bound, 4) if bound > 0 else None,
            "bottleneck": {"name": capacity["bottleneck"], "busy_fraction_at_bound": busy.get(capacity["bottleneck"])},
            "run_bound_per_min": run_bound,
            "run_bound_fraction": round(achieved / run_bound, 4) if run_bound else None,
            "parts_finishable": of_run["parts_finishable"] if of_run else None,
            "capacity": capacity,
        }

    @staticmethod
    def _lockstep_timeouts(coord: dict, controllers: list[dict]) -> dict:
        """Lockstep waits that ran out (0.5 s of wall time) and went on without what they waited for: a decision made
        without every event, a controller's tick planned with older parts or without an announced order. Zero in
        a run that repeats exactly; more means the machine was too loaded for that."""
        return {
            "coordinator_decisions": coord.get("decisions_on_deadline", 0),
            "controllers": {
                c["arm"]: c.get("parts_late", 0) + c.get("missed_assignments", 0) for c in controllers if "arm" in c
            },
        }

    @staticmethod
    def _arm_time(arm_time: dict, held_s: dict, sim_s: float) -> dict:
        """The sim's per-arm fractions, with the time an arm held still for a fixture that was not ready yet (the
        coordinator's count) told apart from waiting for a grant: holding a part at the edge is the pipeline
        working, not a blocked move."""
        out = {}
        for arm, t in arm_time.items():
            held = min(held_s.get(arm, 0.0) / sim_s, t.get("waiting_for_grant", 0.0)) if sim_s > 0 else 0.0
            out[arm] = t | {
                "waiting_for_grant": round(t.get("waiting_for_grant", 0.0) - held, 4),
                "held_at_fixture": round(held, 4),
            }
        return out

    @staticmethod
    def _faults(links: dict, controllers: list[dict]) -> dict:
        """What the bus faults were and what they cost the controllers (goals sent again); empty without faults."""
        if not links:
            return {}
        return {"links": links, "goals_resent": {c["arm"]: c.get("goals_resent", 0) for c in controllers if "arm" in c}}

    def summary(self, wall_s: float, error: str) -> dict:
        sim, coord = self._read(self.nodes[0]), self._read(self.nodes[1])
        controllers = [self._read(n) for n in self.nodes if n.role == "controller"]
        monitor = next((self._read(n) for n in self.nodes if n.role == "monitor"), None)
        heard = self.last_progress
        sim_s = sim.get("sim_seconds", max(self.last_sim_time_s, heard.sim_time_s if heard else 0.0))
        if coord:
            counts = {k: coord.get(k, 0) for k in ("parts_completed", "parts_missed", "parts_failed")}
        else:  # the coordinator died: its last progress message is what is known
            counts = {
                "parts_completed": heard.parts_completed if heard else 0,
                "parts_missed": heard.parts_missed if heard else 0,
                "parts_failed": heard.parts_failed if heard else 0,
            }
        spawned = sim.get("parts_spawned", max(heard.parts_spawned if heard else 0, sum(counts.values())))
        in_progress = (
            coord.get("parts_in_progress", spawned - sum(counts.values()))
            if coord and sim
            else spawned - sum(counts.values())
        )
        completed = counts["parts_completed"]
        processes = [h for n in self.nodes for h in n.history] + [n.record() for n in self.nodes]
        status = "error" if error else ("interrupted" if self.interrupted else "ok")
        return {
            "scene": self.scene.name,
            "arms": len(self.scene.arms),
            "arm_ids": [a.name for a in self.scene.arms],
            "mode": self.options.mode,
            "seed": self.seed,
            "randomised": dict(self.scene.randomised),
            "allocator": coord.get("allocator"),
            "pipeline": coord.get("pipeline"),
            "status": status,
            "error": error,
            "stopped_by": self.interrupted or sim.get("stopped_by", ""),
            "sim_seconds": sim_s,
            "wall_seconds": round(wall_s, 3),
            "loop_wall_seconds": sim.get("loop_wall_seconds"),
            "wall_s_by_stage": sim.get("wall_s_by_stage", {}),
            "parts_spawned": spawned,
            "parts_completed": completed,
            "parts_missed": counts["parts_missed"],
            "parts_failed": counts["parts_failed"],
            "parts_in_progress": max(0, in_progress),
            "throughput_per_min": round(completed / (sim_s / 60.0), 3) if sim_s > 0 else 0.0,
            "utilisation": sim.get("utilisation", {}),
            "arm_time": self._arm_time(sim.get("arm_time", {}), coord.get("held_at_station_s", {}), sim_s),
            **self._capacity(coord.get("capacity"), coord.get("capacity_of_run"), completed, sim_s),
            "capacity_measured": coord.get("capacity_measured"),
            "capacity_of_run": coord.get("capacity_of_run"),
            "feeder_held_s": sim.get("feeder_held_s", {}),
            "inter_arm_contacts": sim.get("inter_arm_contacts", 0),
            "contact_pairs": sim.get("contact_pairs", []),
            "min_separation_m": coord.get("min_separation_m"),
            "closest_pair": coord.get("closest_pair"),
            "grants_denied": coord.get("grants_denied", 0),
            "grants_given": coord.get("grants_given", 0),
            "grant_waits": coord.get("grant_waits", 0),
            "tasks_reassigned": coord.get("tasks_reassigned", 0),
            "grant_requests_open": coord.get("grant_requests_open", {}),
            "held_at_station_s": coord.get("held_at_station_s", {}),
            "lockstep_timeouts": self._lockstep_timeouts(coord, controllers),
            "decision_wall_ms": coord.get("decision_wall_ms", {}),
            "goal_results": sim.get("goal_results", {}),
            "network_faults": self._faults(sim.get("network_faults", {}), controllers),
            "bus_messages_per_arm_per_s": sim.get("bus_messages_per_arm_per_s", {}),
            "latency_p50_ms": sim.get("latency_p50_ms"),
            "latency_p99_ms": sim.get("latency_p99_ms"),
            "round_trip_histogram": sim.get("round_trip_histogram"),
            "bus_messages_out": sim.get("messages_out", {}),
            "dropped_messages": sim.get("dropped_messages", 0)
            + coord.get("dropped_messages", 0)
            + sum(c.get("dropped_messages", 0) for c in controllers)
            + (monitor or {}).get("dropped_messages", 0),
            "arms_lost": sim.get("arms_lost", []),
            "arm_events": coord.get("arm_events", []),
            "respawns": self.respawns,
            "coordinator_takeover": coord.get("takeover"),
            "respawn_requests": self.respawn_requests,
            "monitor": None if monitor is None else {"url": self.monitor_url} | monitor,
            "unfinished_parts": coord.get("unfinished_parts", []),
            "processes": processes,
        }
