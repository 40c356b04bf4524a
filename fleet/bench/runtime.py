"""`fleet bench bus` and `fleet bench run`: what the bus and the process split cost, against raw physics.

- bus: a sim server (in this process) and one real controller process per arm, in lockstep, no
  coordinator and no tasks, so the round trip is the bus and the processes alone.
- run: whole `fleet run` lines on the sorting line (sim, coordinator and controllers as processes,
  parts being picked), timed against stepping the same scene for the same sim time with no
  processes at all (raw physics, with the feeders running).
"""

from __future__ import annotations

import contextlib
import shutil
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from fleet.bus.keys import Keys
from fleet.bus.session import BusEndpoints, open_listening_session
from fleet.common.processes import ChildProcess, stop_children
from fleet.common.scene_loading import load_checked_scene
from fleet.nodes.sim_server import SimServer
from fleet.run.launcher import Launcher, RunOptions
from fleet.sim.world import World

SCENE = "sorting_line"
# controller heartbeats (`ArmStatus`, 5 a wall second; per sim second fewer in a fast lockstep run): not seen by the sim
STATUS_PER_ARM_PER_S = 5.0


@dataclass(frozen=True)
class BusRow:
    arms: int
    ticks: int
    p50_ms: float
    p99_ms: float
    ticks_per_s: float
    messages_per_arm_per_s: float  # both ways, shared messages (parts) split among the arms, heartbeats included
    messages_per_arm_per_s_v1: float  # the same line under protocol 1: a state and a command per arm every tick


def bench_bus(arms: int, ticks: int = 1500) -> BusRow:
    """Round trips state -> answer for `arms` idle controller processes in lockstep, and the bus messages they cost."""
    world = World(load_checked_scene(SCENE, arms=arms))
    keys = Keys("benchbus")
    session, endpoint = open_listening_session(BusEndpoints())
    logs = Path(tempfile.mkdtemp(prefix="clawfleet-benchbus-"))
    procs = [
        ChildProcess(
            [
                sys.executable,
                "-m",
                "fleet.nodes.arm_controller",
                "--scene",
                SCENE,
                "--arms",
                str(arms),
                "--arm",
                name,
                "--run",
                keys.run,
                "--connect",
                endpoint,
            ],
            logs / f"{name}.log",
        ).start()
        for name in world.arms
    ]
    try:
        with contextlib.closing(session):
            server = SimServer(world, session, keys, mode="lockstep", count_contacts=False)
            try:
                server.run_ticks(50)  # every controller up and answering
                server.stats.round_trip_ms.clear()
                server.stats.messages_in.clear()
                server.stats.messages_out.clear()
                start, sim_start = time.perf_counter(), world.sim_time_s
                server.run_ticks(ticks)
                wall = time.perf_counter() - start
                rtt = np.asarray(server.stats.round_trip_ms)
                counted = sum((server.stats.messages_in + server.stats.messages_out).values())
                per_arm = counted / arms / (world.sim_time_s - sim_start) + STATUS_PER_ARM_PER_S
            finally:
                server.close()
    finally:
        stop_children(procs)
        shutil.rmtree(logs, ignore_errors=True)
    hz = world.scene_model.control_hz
    # state + command every tick, a heartbeat every 10th, the parts every tick (shared)
    v1 = 2 * hz + hz / 10 + hz / arms
    return BusRow(
        arms, ticks, float(np.percentile(rtt, 50)), float(np.percentile(rtt, 99)), ticks / wall, round(per_arm, 1), v1
    )


@dataclass(frozen=True)
class RunRow:
    arms: int
    sim_seconds: float
    wall_seconds: (
        float  # the sim's loop, from its first tick to its last (process start-up excluded); median of the repeats
    )
    raw_physics_seconds: float  # the same scene stepped in one process, arms still (median)
    replay_physics_seconds: float  # the same scene stepped in one process with the run's own drive targets (median)
    parts_completed: int
    contacts: int
    p99_ms: float | None  # the bus's state -> answer round trip
    messages_per_arm_per_s: float
    decision_p99_ms: float | None = None  # the coordinator's decisions, wall time (median of the repeats)

    @property
    def realtime_factor(self) -> float:
        return self.sim_seconds / self.wall_seconds

    @property
    def ratio_to_physics(self) -> float:
        return self.wall_seconds / self.raw_physics_seconds

    @property
    def ratio_to_replay(self) -> float:
        return self.wall_seconds / self.replay_physics_seconds


def raw_physics_seconds(arms: int, sim_seconds: float) -> float:
    """Wall time to step the scene for `sim_seconds` in process, feeders running, nobody moving."""
    world = World(load_checked_scene(SCENE, arms=arms))
    ticks = round(sim_seconds * world.scene_model.control_hz)
    start = time.perf_counter()
    world.step(ticks)
    return time.perf_counter() - start


def replay_physics_seconds(arms: int, targets_file: str) -> float:
    """Wall time to step the scene in process with a run's recorded drive targets: its physics and motion, no
    processes."""
    world = World(load_checked_scene(SCENE, arms=arms))
    log = np.load(targets_file)
    position, velocity, gripper = log["position"].tolist(), log["velocity"].tolist(), log["gripper"].tolist()
    sim_arms = list(world.arms.values())
    start = time.perf_counter()
    for p_tick, v_tick, g_tick in zip(position, velocity, gripper):
        for arm, p, v, g in zip(sim_arms, p_tick, v_tick, g_tick):
            arm.set_targets(p, v, g)
        world.step()
    return time.perf_counter() - start


def bench_run(
    arms: int, sim_seconds: float = 60.0, repeats: int = 3, on_run: Callable[[int], None] | None = None
) -> RunRow:
    """Lockstep `fleet run`s of the sorting line, each followed at once by raw physics (arms still) and by a replay of
    its own drive targets (same motion) of the same scene and sim time; medians, so the machine's drift hits all
    alike."""
    walls, raws, replays, decisions, summary = [], [], [], [], {}
    with tempfile.TemporaryDirectory(prefix="clawfleet-benchrun-") as tmp:
        targets = str(Path(tmp) / "targets.npz")
        for k in range(repeats):
            if on_run is not None:
                on_run(k)
            with Launcher(
                RunOptions(scene=SCENE, arms=arms, duration_s=sim_seconds, run_id="benchrun", record_targets=targets)
            ) as launcher:
                summary = launcher.run()
            if summary["status"] != "ok":
                raise RuntimeError(f"the benchmark run failed: {summary['error']}")
            walls.append(summary["loop_wall_seconds"])
            decisions.append(summary["decision_wall_ms"].get("p99"))
            raws.append(raw_physics_seconds(arms, sim_seconds))
            replays.append(replay_physics_seconds(arms, targets))
    per_arm = sum(summary["bus_messages_per_arm_per_s"].values()) + STATUS_PER_ARM_PER_S
    return RunRow(
        arms,
        summary["sim_seconds"],
        float(np.median(walls)),
        float(np.median(raws)),
        float(np.median(replays)),
        summary["parts_completed"],
        summary["inter_arm_contacts"],
        summary["latency_p99_ms"],
        round(per_arm, 1),
        float(np.median(decisions)) if None not in decisions else None,
    )


def plot_run_rows(rows: list[RunRow], path: Path) -> Path:
    """Wall time over raw physics (still, and the replay of the same motion) and sim seconds per wall second,
    against the number of arms."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    arms = [r.arms for r in rows]
    fig, (ratio, speed) = plt.subplots(1, 2, figsize=(9, 3.6))
    ratio.plot(arms, [r.ratio_to_physics for r in rows], "o-", label="wall / raw physics (arms still)")
    ratio.plot(arms, [r.ratio_to_replay for r in rows], "s-", label="wall / replay (same motion)")
    ratio.axhline(1.7, color="grey", ls="--", lw=1, label="goal 1.7")
    ratio.set_xlabel("arms")
    ratio.set_ylim(bottom=0)
    ratio.legend(fontsize=8)
    speed.plot(arms, [r.realtime_factor for r in rows], "o-", color="#55A868")
    speed.axhline(2.0, color="grey", ls="--", lw=1, label="2x real time")
    speed.set_xlabel("arms")
    speed.set_ylabel("sim s per wall s")
    speed.set_yscale("log")
    speed.yaxis.set_major_formatter(matplotlib.ticker.ScalarFormatter())
    speed.yaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    speed.set_yticks([1, 2, 5, 10, 20])
    speed.legend(fontsize=8)
    fig.suptitle(f"fleet run {SCENE} --arms N, {rows[0].sim_seconds:.0f} s of sim time", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


@dataclass(frozen=True)
class LineRow:
    scene: str
    arms: int
    allocator: str
    throughput_per_min: float
    parts_completed: int
    parts_spawned: int
    contacts: int
    min_separation_m: float | None
    grants_denied: int
    grants_given: int = 0
    bound_fraction: float | None = None  # of the line's nominal capacity bound
    run_bound_fraction: float | None = None  # of the bound of this run's own arrivals


def bench_lines(
    cases: list[tuple[str, int | None]], allocators: list[str], sim_seconds: float, seed: int = 0
) -> list[LineRow]:
    """Lockstep runs of each (scene, arms) with each allocator; figures are per sim time, so load does not move them."""
    rows = []
    for scene, arms in cases:
        for allocator in allocators:
            options = RunOptions(
                scene=scene, arms=arms, duration_s=sim_seconds, seed=seed, allocator=allocator, run_id="benchlines"
            )
            with Launcher(options) as launcher:
                s = launcher.run()
            if s["status"] != "ok":
                raise RuntimeError(f"{scene} with {allocator}: {s['error']}")
            rows.append(
                LineRow(
                    s["scene"],
                    s["arms"],
                    allocator,
                    s["throughput_per_min"],
                    s["parts_completed"],
                    s["parts_spawned"],
                    s["inter_arm_contacts"],
                    s["min_separation_m"],
                    s["grants_denied"],
                    s["grants_given"],
                    s.get("bound_fraction"),
                    s.get("run_bound_fraction"),
                )
            )
    return rows


@dataclass(frozen=True)
class MonitorRow:
    variant: str
    loop_wall_seconds: float  # median over the repeats
    ratio_to_plain: float
    monitor_frames_per_s: float | None


MONITOR_VARIANTS = ("no monitor", "monitor, no page open", "monitor + headless chromium")


def _browse(url: str) -> ChildProcess:
    """A headless Chromium showing `url` (software WebGL), as a viewer would (no sandbox: CI runs as root)."""
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise RuntimeError("the browser variant needs chromium (apt-get install chromium)")
    profile = Path(tempfile.mkdtemp(prefix="clawfleet-chromium-"))
    return ChildProcess(
        [
            chromium,
            "--headless=new",
            "--enable-unsafe-swiftshader",
            "--no-first-run",
            "--no-sandbox",
            f"--user-data-dir={profile}",
            "--window-size=1280,800",
            "--remote-debugging-port=0",
            url,
        ],
        profile / "chromium.log",
    ).start()


def _monitored_run(scene: str, arms: int | None, sim_seconds: float, variant: str) -> dict:
    browsers: list[ChildProcess] = []

    def on_message(text: str) -> None:
        if variant == MONITOR_VARIANTS[2] and text.startswith("monitor: http"):
            browsers.append(_browse(text.split(" ", 1)[1]))

    options = RunOptions(
        scene=scene,
        arms=arms,
        duration_s=sim_seconds,
        run_id="benchmonitor",
        monitor=variant != MONITOR_VARIANTS[0],
        monitor_port=0,
    )
    try:
        with Launcher(options, on_message=on_message) as launcher:
            summary = launcher.run()
    finally:
        for b in browsers:
            b.kill()
    if summary["status"] != "ok":
        raise RuntimeError(f"the benchmark run failed: {summary['error']}")
    if variant == MONITOR_VARIANTS[2] and not summary["monitor"].get("most_pages_open"):
        raise RuntimeError("the headless chromium never opened the monitor's page")
    return summary


def bench_monitor(
    scene: str = "sorting_line", arms: int | None = 4, sim_seconds: float = 30.0, repeats: int = 3, browser: bool = True
) -> list[MonitorRow]:
    """Lockstep runs without and with the monitor (and a browser on it), interleaved; the sim loop's wall time
    compared."""
    variants = MONITOR_VARIANTS if browser else MONITOR_VARIANTS[:2]
    walls: dict[str, list[float]] = {v: [] for v in variants}
    fps: dict[str, list[float]] = {v: [] for v in variants}
    for _ in range(repeats):
        for v in variants:
            s = _monitored_run(scene, arms, sim_seconds, v)
            walls[v].append(s["loop_wall_seconds"])
            if s["monitor"]:
                fps[v].append(s["monitor"]["frames_per_s"])
    plain = float(np.median(walls[variants[0]]))
    return [
        MonitorRow(
            v,
            float(np.median(walls[v])),
            float(np.median(walls[v])) / plain,
            float(np.median(fps[v])) if fps[v] else None,
        )
        for v in variants
    ]


@dataclass
class RecordRow:
    """Lockstep runs without and with a recording: medians of the sim loop's wall time, the run's (from the first
    tick's wait to the finished file: `wall_seconds` of the summary) and the whole run's (from starting the
    processes, the recorder's included, to the finished file)."""

    variant: str
    loop_wall_seconds: float
    run_wall_seconds: float
    whole_wall_seconds: float
    loop_ratio: float
    run_ratio: float
    whole_ratio: float
    mb_per_sim_minute: float | None
    messages_per_sim_s: float | None


def bench_record(
    scene: str = "assembly_line", arms: int | None = None, sim_seconds: float = 60.0, repeats: int = 3
) -> list[RecordRow]:
    """`fleet run` against `fleet run --record`, interleaved: what recording costs, and how big the file grows."""
    walls: dict[str, list[tuple[float, float, float]]] = {"plain": [], "recorded": []}
    sizes, messages = [], []
    with tempfile.TemporaryDirectory(prefix="clawfleet-bench-record-") as tmp:
        for i in range(repeats):
            for variant in walls:
                path = Path(tmp) / f"run{i}.mcap" if variant == "recorded" else None
                options = RunOptions(
                    scene=scene,
                    arms=arms,
                    duration_s=sim_seconds,
                    run_id="benchrecord",
                    record=str(path) if path else None,
                )
                started = time.monotonic()
                with Launcher(options, on_message=lambda _text: None) as launcher:
                    summary = launcher.run()
                whole_s = time.monotonic() - started
                if summary["status"] != "ok" or (path and not summary.get("recording")):
                    raise RuntimeError(f"the benchmark run failed: {summary['error'] or 'no recording'}")
                walls[variant].append((summary["loop_wall_seconds"], summary["wall_seconds"], whole_s))
                if path:
                    sizes.append(summary["recording"]["bytes"] / 1e6 / (summary["sim_seconds"] / 60.0))
                    messages.append(summary["recording"]["messages_written"] / summary["sim_seconds"])
    plain = [float(np.median([w[k] for w in walls["plain"]])) for k in range(3)]
    rows = []
    for variant, w in walls.items():
        medians = [float(np.median([x[k] for x in w])) for k in range(3)]
        recorded = variant == "recorded"
        rows.append(
            RecordRow(
                variant,
                *medians,
                *(m / p for m, p in zip(medians, plain)),
                float(np.median(sizes)) if recorded else None,
                float(np.median(messages)) if recorded else None,
            )
        )
    return rows
