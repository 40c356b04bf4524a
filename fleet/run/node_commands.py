"""The processes a run starts, with their arguments: the sim, the coordinator and one controller per arm, the monitor
and the recorder."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

from coordinator.cadence import moves_need_grants
from fleet.bus.bus_config import BusConfigSet
from fleet.common.processes import stop_children, write_text_atomically
from fleet.run.hosts import Hosts
from fleet.run.run_node import (
    COORDINATOR_RESPAWN_TIMEOUT_S,
    RECORDER_GRACE_S,
    RECORDER_START_S,
    Node,
    read_report,
    server_url_file,
)
from fleet.run.run_options import RunOptions
from scenes.schema import Scene

PERCEPTION_START_S = 60.0  # wall seconds a line that works from its cameras waits for its perception process


class NodeCommands:
    """The processes a run starts and their arguments, in the run's folder `dir`; `endpoint` is where the sim
    listens (given, or set once the sim said where)."""

    def __init__(
        self,
        options: RunOptions,
        scene: Scene,
        dir: Path,
        bus: BusConfigSet | None,
        hosts: Hosts | None,
        endpoint: str = "",
    ) -> None:
        self.options, self.scene, self.dir = options, scene, dir
        self.bus, self.hosts, self.endpoint = bus, hosts, endpoint

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
            str(self.scene.seed),
            *self._bus_args(listen, node),
            *extra,
        ]
        if o.perception == "cameras":  # the line works from what its cameras show (`docs/perception.md`)
            argv += ["--perception", "cameras"]
        if o.arms is not None:
            argv += ["--arms", str(o.arms)]
        report, log = self.dir / f"{name}.json", self.dir / f"{name}.log"
        started = Node(role, name, [*argv, "--report", str(report)], report, log)
        started.starts = max(0, dict(o.incarnations).get(name, 1) - 1)  # restored: the start the snapshot was in
        return started

    def sim_node(self) -> Node:
        o = self.options
        sim_args = ["--duration", str(o.duration_s), "--mode", o.mode, "--speed", str(o.speed), "--coordinator"]
        sim_args += ["--rt"] if o.realtime_priority and o.mode == "realtime" else []
        if o.pause_at:
            sim_args += ["--pause-at", ",".join(repr(t) for t in o.pause_at)]
        if not o.listen:
            sim_args += ["--endpoint-file", str(self.dir / "endpoint")]
        if o.record_targets:
            sim_args += ["--record-targets", o.record_targets]
        if cameras := self.cameras():
            sim_args += ["--cameras", cameras, "--camera-encoding", o.rgb_encoding()]
        if o.perception == "cameras":  # the line's first frame is seen: the clock starts once perception listens
            sim_args += ["--await-perception", repr(PERCEPTION_START_S)]
        if self._allocator_sees():  # and once the allocator that sees does
            sim_args += ["--await-eyes", repr(PERCEPTION_START_S)]
        if o.record:  # what the bus carries, as the sim hears it, for the recorder (no second copy on the wire)
            sim_args += ["--spool", str(self.spool_path)]
        if o.respawn:
            sim_args += ["--coordinator-timeout", str(COORDINATOR_RESPAWN_TIMEOUT_S)]
        if self.bus is not None:  # the run's own router: what its access control refuses is counted
            sim_args += ["--router-audit", str(self.dir / "router.log")]
        for flag, value in (("--latency-ms", o.latency_ms), ("--jitter-ms", o.jitter_ms), ("--loss", o.loss)):
            if value is not None:
                sim_args += [flag, repr(value)]
        sim_args += ["--allocator", o.allocator, *self._snapshot_args(), *self._from()]
        if o.reseed is not None:
            sim_args += ["--reseed", str(o.reseed)]
        return self._node("sim", "sim_server", "fleet.nodes.sim_server", sim_args, listen=bool(o.listen))

    def cameras(self) -> str | None:
        """The cameras the sim renders: those asked for, and with `--perception cameras` or an allocator that sees
        every fixed one (the line, or its brain, sees through all of them)."""
        named = self.options.cameras
        if named == "all" or not (self.options.perception == "cameras" or self._allocator_sees()):
            return named
        fixed = [c.name for c in self.scene.cameras if c.arm is None]
        return ",".join(dict.fromkeys([*(n.strip() for n in (named or "").split(",") if n.strip()), *fixed]))

    def _allocator_sees(self) -> bool:
        """Whether the run's allocator asks to see the cameras (a plug-in is loaded only for this question)."""
        from coordinator.allocator_plugins import sees

        return sees(self.options.allocator)

    def _snapshot_args(self) -> list[str]:
        """The sim's snapshot flags: when (sim seconds) and where."""
        o = self.options
        if not o.snapshot_dir:
            return []
        args = ["--snapshot-dir", o.snapshot_dir]
        if o.snapshot_at:
            args += ["--snapshot-at", ",".join(repr(t) for t in o.snapshot_at)]
        if o.snapshot_every_s:
            args += ["--snapshot-every", repr(o.snapshot_every_s)]
        return args

    def client_nodes(self) -> list[Node]:
        """The coordinator and one controller per arm, connecting to the sim's endpoint."""
        o = self.options
        nodes = [
            self._node(
                "coordinator",
                "coordinator",
                "fleet.nodes.coordinator_node",
                ["--mode", o.mode, "--allocator", o.allocator, "--roster", *([] if o.pipeline else ["--no-pipeline"])],
            )
        ]
        for arm in self.scene.arms:
            grants = ["--grants"] if moves_need_grants(self.scene) else []  # a lone arm has nobody to ask about
            extra = ["--arm", arm.name, "--roster", *grants] + (["--rt"] if o.realtime_priority else [])
            nodes.append(self._node("controller", arm.name, "fleet.nodes.arm_controller", extra))
        for node in nodes:
            node.counts_starts = True
            node.restore_args = self._from()
        return nodes

    def _from(self) -> list[str]:
        """Where a restored run's node starts from (until the line runs: `Node.restore_args`)."""
        return ["--from", self.options.restore_from] if self.options.restore_from else []

    def _attached_node(self, role: str, module: str, login: str, extra: list[str], url: bool = False) -> Node:
        """A node that attaches to the running line over the bus with `login` (it asks the sim for the scene, so
        it takes no scene flags); with `url`, it writes where it serves to `<role>_url` in the run's folder."""
        report, log = self.dir / f"{role}.json", self.dir / f"{role}.log"
        argv = [*self._here(role), module, "--run", self.options.run_id, *self._bus_args(False, login), *extra]
        if url:
            argv += ["--url-file", str(server_url_file(self.dir, role))]
        return Node(role, role, [*argv, "--report", str(report)], report, log)

    def monitor_node(self) -> Node:
        """The browser monitor."""
        o = self.options
        extra = ["--host", o.monitor_host, "--port", str(o.monitor_port)]
        return self._attached_node("monitor", "fleet.nodes.monitor_node", "monitor", extra, url=True)

    def perception_node(self) -> Node:
        """The perception node, with the `perception` login: the parts the fixed cameras show, as tracks."""
        extra = ["--cameras", self.cameras() or "all"]
        return self._attached_node("perception", "fleet.nodes.perception_node", "perception", extra)

    def rosbridge_node(self) -> Node:
        """The rosbridge server, with the `ros` login."""
        extra = ["--port", str(self.options.rosbridge_port), "--max-rate-hz", str(self.options.ros_max_rate_hz)]
        return self._attached_node("rosbridge", "fleet.nodes.rosbridge_node", "ros", extra, url=True)

    def foxglove_node(self) -> Node:
        """The Foxglove server, with the `ros` login (a front end for robotics tools: e-stop, pause, resume)."""
        extra = ["--port", str(self.options.foxglove_port), "--max-rate-hz", str(self.options.ros_max_rate_hz)]
        return self._attached_node("foxglove", "fleet.nodes.foxglove_node", "ros", extra, url=True)

    def ros2_node(self) -> Node:
        """The native ROS 2 node (rmw_zenoh's layout on the run's router), with the `ros` login."""
        extra = ["--domain-id", str(self.options.ros2_domain), "--max-rate-hz", str(self.options.ros_max_rate_hz)]
        return self._attached_node("ros2", "fleet.nodes.ros2_node", "ros", extra)

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

    def finish_recording(self, recorder: Node, summary: dict, on_message: Callable[[str], None]) -> dict:
        """Hand the `recorder` the summary and let it finish the file; what it reports."""
        write_text_atomically(str(self.dir / "summary.json"), json.dumps(summary, sort_keys=True))
        stop_children([recorder.child], RECORDER_GRACE_S)
        report = read_report(recorder.report)
        if not report:
            on_message(
                f"the recorder did not finish {self.options.record}: {recorder.log_tail() or 'no output'}; "
                "writing the recording again from the run's spool"
            )
            report = self._record_spool_once(recorder, on_message)
        if not report:
            summary["status"] = "error"
            summary["error"] = f"the recording {self.options.record} could not be written (see the messages above)"
        return report

    def _record_spool_once(self, recorder: Node, on_message: Callable[[str], None]) -> dict:
        """A new recorder writes the whole spool (the sim appended every message to it) and exits: what it reports,
        or {} if it could not."""
        report, log = self.dir / "recorder_again.json", self.dir / "recorder_again.log"
        argv = [a for a in recorder.argv if a != "--hold"]
        argv[argv.index("--report") + 1] = str(report)
        with open(log, "wb") as out:
            try:
                subprocess.run([*argv, "--once"], stdout=out, stderr=subprocess.STDOUT, timeout=RECORDER_GRACE_S)
            except subprocess.TimeoutExpired:
                pass  # killed by run(): no report
        written = read_report(report)
        if not written:
            tail = log.read_text(errors="replace").strip().splitlines()[-1:] if log.exists() else []
            on_message(f"the recording could not be written again: {tail[0] if tail else 'no output'}")
        return written
