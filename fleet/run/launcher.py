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

import signal
import sys
import threading
import time
from collections.abc import Callable

import zenoh

from fleet.bus.bus_config import BusConfigError, BusConfigSet, write_run_bus
from fleet.bus.codec import DropCounter
from fleet.bus.keys import Keys
from fleet.bus.messages import Progress
from fleet.bus.session import BusEndpoints, free_loopback_port, open_session
from fleet.common.processes import read_when_written, stop_children
from fleet.common.scene_loading import load_checked_scene
from fleet.run.disk_watch import room_problem, run_disks
from fleet.run.hosts import Hosts, load_hosts
from fleet.run.node_commands import NodeCommands
from fleet.run.node_factory import NodeFactory, adopting, kept_factory
from fleet.run.run_folder import close_run_folder, make_run_folder
from fleet.run.run_node import (
    RECORDER_GRACE_S,
    STOP_GRACE_S,
    Node,
    server_url_file,
)
from fleet.run.run_options import RunOptions
from fleet.run.run_summary import RunEnd, RunSummary, count_problems
from fleet.run.supervision import Supervision
from scenes.schema import Scene


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
        """`factory`: a node factory that outlives this run; else this process's kept one
        (`node_factory.keep_factory`: a sweep's worker keeps one for all its runs), else, with `fork_nodes`, the
        run starts its own and closes it at the end."""
        self.options = options
        self.on_message = on_message or (lambda text: print(text, file=sys.stderr, flush=True))
        self.scene = load_checked_scene(options.scene, arms=options.arms, seed=options.seed)
        self.seed = self.scene.seed
        self.bus, self.hosts = placement(options.bus_config, options.hosts, self.scene)
        self.dir = make_run_folder()
        self.disk = run_disks(self.dir, options.record)
        if self.bus is None and self.secure_by_default:
            arms = [a.name for a in self.scene.arms]
            ros = self.options.ros2_domain, self.options.ros2_arms
            self.bus = write_run_bus(self.dir / "bus", arms, free_loopback_port(), *ros)
        # without --listen the sim picks a free loopback port and says which (`endpoint`, set once it has)
        self.commands = NodeCommands(options, self.scene, self.dir, self.bus, self.hosts, options.listen or "")
        self.nodes: list[Node] = []
        self.recorder: Node | None = None  # started before the clients, stopped after the summary
        # forks the nodes; its own is closed after they all stopped
        self.factory = (factory or kept_factory()) if options.fork_nodes else None
        self._own_factory = False
        self.drops = DropCounter()  # what the launcher heard and refused (malformed, or not true of this line)
        self.interrupted = ""  # why the launcher was told to stop (a signal's name, or a caller's reason)
        self.keep_dir = options.keep_logs
        self.supervision = Supervision(
            options,
            self.scene,
            self.dir,
            self.disk,
            self.nodes,
            self.drops,
            self.on_message,
            on_progress,
            stopped=lambda: self.interrupted,
        )

    @property
    def on_progress(self) -> Callable[[Progress], None] | None:
        """Called with each progress report the line says (set it once the launcher exists, to act on the line)."""
        return self.supervision.on_progress

    @on_progress.setter
    def on_progress(self, callback: Callable[[Progress], None] | None) -> None:
        self.supervision.on_progress = callback

    def server_url(self, role: str, timeout_s: float = 60.0) -> str:
        """Where this run's serving node `role` (`monitor`, `rosbridge`, `foxglove`) serves, once it says;
        RuntimeError if it does not within `timeout_s`."""
        url = read_when_written(server_url_file(self.dir, role), timeout_s)
        if url is None:
            raise RuntimeError(f"the {role} server did not say where it serves within {timeout_s:g} s")
        return url

    @property
    def endpoint(self) -> str:
        """Where the sim listens ("" until it says, where it picks its own port)."""
        return self.commands.endpoint

    @property
    def secure_by_default(self) -> bool:
        """Whether this run makes its own secure bus: unless told `insecure`, or given endpoints or a Zenoh config."""
        o = self.options
        return not (o.insecure or o.listen or o.connect or o.zenoh_config)

    def client_endpoints(self, role: str = "monitor") -> BusEndpoints:
        """How another process joins this run's bus as `role` (a node name: `monitor` may stop, pause and pace the
        line; `recorder` and `launcher` only listen): its login on a secure bus, the sim's endpoint otherwise."""
        if self.bus is not None:
            return BusEndpoints(config_file=self.bus.config_for(role))
        return BusEndpoints(connect=(self.endpoint,))

    # --- processes ------------------------------------------------------------------

    def _start(self, node: Node) -> Node:
        node.child.factory = self.factory
        node.start()
        return node

    def __enter__(self) -> Launcher:
        try:
            if short := room_problem(self.options.record):
                raise RunError(short)
            if self.options.fork_nodes and self.factory is None:
                self.factory, self._own_factory = NodeFactory(self.dir / "node_factory.log"), True
            elif self.factory is not None and not self.factory.adopt:
                adopting(+1)  # a kept factory's nodes come here if it dies under this run
            commands = self.commands
            sim = commands.sim_node()
            self.nodes[:] = [self._start(sim)]  # the list supervision watches
            if self.options.record:  # beside the sim: it waits for the sim's spool while both import
                self.recorder = self._start(commands.recorder_node())
            if not self.endpoint or self.bus is not None:  # the sim listens: clients may connect (a client that
                commands.endpoint = self._await_endpoint(sim)  # finds no router gives up)
            self.nodes += commands.client_nodes()
            if self.options.monitor:
                self.nodes.append(commands.monitor_node())
            if self.options.perception == "cameras":
                self.nodes.append(commands.perception_node())
            if self.options.rosbridge_port is not None:
                self.nodes.append(commands.rosbridge_node())
            if self.options.foxglove_port is not None:
                self.nodes.append(commands.foxglove_node())
            if self.options.ros2_domain is not None:
                self.nodes.append(commands.ros2_node())
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
        elif self.factory is not None and not self.factory.adopt:
            adopting(-1)
        close_run_folder(self.dir, self.keep_dir)

    def stop_all(self) -> None:
        """SIGTERM every node (the sim first, so it writes its figures), SIGKILL what is left after a grace period."""
        stop_children([n.child for n in self.nodes], STOP_GRACE_S)

    # --- the run --------------------------------------------------------------------
    def run(self) -> dict:
        """Run until the sim's duration ends, a node crashes or the launcher is told to stop; then the summary."""
        started = time.monotonic()
        # Ctrl-C and SIGTERM stop the line cleanly; only the main thread may take signals (a line run from another
        # thread is stopped by whoever owns that thread, or by its own duration)
        signals = (signal.SIGINT, signal.SIGTERM) if threading.current_thread() is threading.main_thread() else ()
        previous = {sig: signal.signal(sig, self._on_signal) for sig in signals}
        error = ""
        try:
            try:
                error = self._run_on_bus(self.client_endpoints("launcher"))
            except zenoh.ZError as exc:  # the sim went before the launcher reached its bus
                error = self.supervision.unreachable(str(exc))
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
            self.stop_all()
        if error:
            self.keep_dir = True
        summary = RunSummary(self.run_end()).summary(time.monotonic() - started, error)
        problems = count_problems(summary)
        if problems and summary["status"] == "ok":  # every part is counted once, or the run says so
            summary["status"] = "error"
            summary["error"] = f"the run's counts do not add up: {'; '.join(problems)}"
        if self.recorder is not None:
            summary["recording"] = self.commands.finish_recording(self.recorder, summary, self.on_message)
            summary["processes"].append(self.recorder.record())
            summary["wall_seconds"] = round(time.monotonic() - started, 3)  # until the file is whole
        return summary

    def _run_on_bus(self, mine: BusEndpoints) -> str:
        """Supervise the line from the launcher's own session until it ends; why it ended ("" for a clean end)."""
        with open_session(mine) as session:
            return self.supervision.watch(session, Keys(self.options.run_id), self.factory)

    def _on_signal(self, signum: int, _frame: object) -> None:
        self.interrupted = signal.Signals(signum).name

    def run_end(self) -> RunEnd:
        """What this launcher knows of the run as it ends, for its summary."""
        return RunEnd(
            scene=self.scene,
            seed=self.seed,
            mode=self.options.mode,
            secure_bus=self.bus is not None and self.bus.secure,
            nodes=list(self.nodes),
            drops=self.drops,
            last_progress=self.supervision.last_progress,
            last_sim_time_s=self.supervision.last_sim_time_s,
            interrupted=self.interrupted,
            respawns=self.supervision.respawns,
            respawn_requests=list(self.supervision.respawn_requests),
            server_urls=dict(self.supervision.server_urls),
        )
