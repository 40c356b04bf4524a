"""What `fleet run` is asked for: one value the launcher, the node commands and the front ends that start lines
(sweeps, benchmarks, tests) share."""

from __future__ import annotations

from dataclasses import dataclass

from coordinator.ledger import PIPELINE_DEFAULT
from fleet.ros.names import DEFAULT_MAX_RATE_HZ
from fleet.run.run_node import HUNG_COORDINATOR_S


@dataclass(frozen=True)
class RunOptions:
    """What `fleet run` was asked for."""

    scene: str = "assembly_line"
    arms: int | None = None
    duration_s: float = 120.0  # the sim time the run ends at (a restored run too: `restore_options` adds its start)
    mode: str = "lockstep"
    speed: float = 1.0
    seed: int | None = None
    respawn: bool = False
    hung_after_s: float = HUNG_COORDINATOR_S  # with `respawn`: a live coordinator silent this long (wall) is replaced
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
    foxglove_port: int | None = None  # serve the line to the Foxglove app on this port (0: any free one)
    rosbridge_port: int | None = None  # serve the line over rosbridge's WebSocket on this port (0: any free one)
    ros2_domain: int | None = None  # publish the line's ROS 2 topics natively (rmw_zenoh) in this ROS domain
    ros2_arms: tuple[str, ...] | None = None  # the arms an outside ROS 2 stack (login `ros_client`) may drive; all
    ros_max_rate_hz: float = DEFAULT_MAX_RATE_HZ  # the ROS front ends' topics at most this often (wall); 0: no cap
    record_targets: str | None = None  # the sim saves every tick's drive targets here (benchmarks replay them)
    cameras: str | None = None  # the scene's cameras to render: all, or names joined by commas (None: no rendering)
    camera_encoding: str = "auto"  # how RGB images travel (`fleet.bus.images`); auto: `rgb_encoding()`
    # cameras: the line works from what its fixed cameras show: a perception node detects and tracks the parts, the
    # coordinator and the controllers get only its parts (`docs/perception.md`); truth: the sim's, no perception node
    perception: str = "truth"
    record: str | None = None  # an MCAP file: the sim spools the bus from before its first client, a recorder writes it
    bus_config: str | None = None  # a `fleet bus-config` directory: the sim a router, each node its own login
    # without a bus config, listen or connect endpoints or a Zenoh config, a run makes its own secure bus on loopback
    # (TLS, logins, access control: `write_run_bus`); `insecure` opts out (any local process may then command it)
    insecure: bool = False
    hosts: str | None = None  # a hosts file: the network namespace each node starts in (`fleet/run/hosts.py`)
    # nodes forked from one process that imported once (`fleet/run/node_factory.py`), not exec'd each
    fork_nodes: bool = True
    latency_ms: float | None = None  # network faults on every link (None: the scene's)
    jitter_ms: float | None = None
    loss: float | None = None
    pause_at: tuple[float, ...] = ()  # sim seconds at which the line pauses until a user resumes it
    snapshot_at: tuple[float, ...] = ()  # sim seconds at which the sim takes a snapshot of the run (lockstep)
    snapshot_every_s: float | None = None
    snapshot_dir: str | None = None  # where snapshots are written
    restore_from: str | None = None  # a snapshot every node starts from (`scene` is then the one it holds)
    reseed: int | None = None  # with `restore_from`: the feeders draw their arrivals from this seed from there on
    incarnations: tuple[tuple[str, int], ...] = ()  # with `restore_from`: each node starts in this incarnation

    def on_loopback_here(self) -> bool:
        """Whether every node runs on this machine on a bus the run makes itself (no hosts file, endpoints, bus
        directory or Zenoh config of the user's)."""
        return not (self.hosts or self.listen or self.connect or self.bus_config or self.zenoh_config)

    def rgb_encoding(self) -> str:
        """How RGB images travel: as asked, or (auto) raw arrays where the bus stays on this machine (nothing to
        encode in the sim's loop; the recorder and the ROS front ends pack PNG in their own processes), PNG where
        it may cross a network."""
        if self.camera_encoding != "auto":
            return self.camera_encoding
        return "raw" if self.on_loopback_here() else "png"
