"""`fleet bench ...`: every benchmark, one sub-command each."""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path

from rich.table import Table

from fleet.cli import bench_cameras, bench_perception
from fleet.cli.errors import (
    err,
    out,
    seed_number,
)


def print_bench(table: Table, rows: list, as_json: bool) -> int:
    """A benchmark's table, and with `--json` its rows as one JSON line (the last on stdout)."""
    out.print(table)
    if as_json:
        print(json.dumps([r.__dict__ for r in rows]))
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    from fleet.bench.physics import bench_physics

    table = Table("arms", "parts on belt", "physics steps/s", "sim s per wall s")
    rows = []
    for n in args.arms:
        row = bench_physics(n, args.seconds)
        rows.append(row)
        table.add_row(str(n), str(row.parts_active), f"{row.steps_per_s:,.0f}", f"{row.sim_s_per_wall_s:.1f}")
    out.print(table)
    if args.json:
        print(json.dumps([{"arms": r.arms, "steps_per_s": round(r.steps_per_s, 1)} for r in rows]))
    return 0


def cmd_bench_bus(args: argparse.Namespace) -> int:
    from fleet.bench.runtime import bench_bus

    table = Table(
        "arms", "ticks", "round trip p50 (ms)", "p99 (ms)", "lockstep ticks/s", "msgs/arm/sim s", "protocol 1", "fewer"
    )
    rows = []
    for n in args.arms:
        row = bench_bus(n, args.ticks)
        rows.append(row)
        table.add_row(
            str(n),
            str(row.ticks),
            f"{row.p50_ms:.2f}",
            f"{row.p99_ms:.2f}",
            f"{row.ticks_per_s:,.0f}",
            f"{row.messages_per_arm_per_s:.1f}",
            f"{row.messages_per_arm_per_s_v1:.0f}",
            f"{row.messages_per_arm_per_s_v1 / row.messages_per_arm_per_s:.1f}x",
        )
    return print_bench(table, rows, args.json)


def cmd_bench_run(args: argparse.Namespace) -> int:
    from fleet.bench.runtime import bench_run, plot_run_rows

    table = Table(
        "arms",
        "sim s",
        "wall s",
        "sim s per wall s",
        "wall / raw physics (still)",
        "wall / replay (same motion)",
        "parts done",
        "contacts",
        "bus msgs/arm/s",
        "bus round trip p99 (ms)",
        "decisions p99 (ms)",
    )
    rows = []
    for n in args.arms:
        say = lambda k, n=n: err.print(f"{n} arms: run {k + 1} of {args.repeats}", highlight=False)  # noqa: E731
        row = bench_run(n, args.seconds, args.repeats, on_run=say)
        rows.append(row)
        table.add_row(
            str(n),
            f"{row.sim_seconds:.0f}",
            f"{row.wall_seconds:.1f}",
            f"{row.realtime_factor:.2f}",
            f"{row.ratio_to_physics:.2f}",
            f"{row.ratio_to_replay:.2f}",
            str(row.parts_completed),
            str(row.contacts),
            f"{row.messages_per_arm_per_s:.0f}",
            f"{row.p99_ms}",
            "-" if row.decision_p99_ms is None else f"{row.decision_p99_ms:.1f}",
        )
    out.print(table)
    if args.plot:
        err.print(f"figure: {plot_run_rows(rows, Path(args.plot))}", highlight=False)
    if args.json:
        print(
            json.dumps(
                [
                    r.__dict__
                    | {
                        "realtime_factor": r.realtime_factor,
                        "ratio_to_physics": r.ratio_to_physics,
                        "ratio_to_replay": r.ratio_to_replay,
                    }
                    for r in rows
                ]
            )
        )
    return 0


def cmd_bench_monitor(args: argparse.Namespace) -> int:
    from fleet.bench.runtime import bench_monitor

    rows = bench_monitor(args.scene, args.arms, args.seconds, args.repeats, browser=not args.no_browser)
    table = Table("variant", "sim loop wall s (median)", "ratio to no monitor", "monitor frames/s")
    for r in rows:
        table.add_row(
            r.variant,
            f"{r.loop_wall_seconds:.2f}",
            f"{r.ratio_to_plain:.3f}",
            "-" if r.monitor_frames_per_s is None else f"{r.monitor_frames_per_s:.1f}",
        )
    return print_bench(table, rows, args.json)


def cmd_bench_record(args: argparse.Namespace) -> int:
    from fleet.bench.runtime import bench_record

    rows = bench_record(args.scene, args.arms, args.seconds, args.repeats)
    table = Table(
        "variant",
        "sim loop wall s",
        "run wall s",
        "whole run wall s",
        "loop ratio",
        "run ratio",
        "whole run ratio",
        "MB / sim minute",
        "messages / sim s",
    )
    for r in rows:
        table.add_row(
            r.variant,
            f"{r.loop_wall_seconds:.2f}",
            f"{r.run_wall_seconds:.2f}",
            f"{r.whole_wall_seconds:.2f}",
            f"{r.loop_ratio:.3f}",
            f"{r.run_ratio:.3f}",
            f"{r.whole_ratio:.3f}",
            "-" if r.mb_per_sim_minute is None else f"{r.mb_per_sim_minute:.2f}",
            "-" if r.messages_per_sim_s is None else f"{r.messages_per_sim_s:.0f}",
        )
    return print_bench(table, rows, args.json)


def cmd_bench_collision(args: argparse.Namespace) -> int:
    from fleet.bench.coordinator import bench_collision

    table = Table(
        "arms", "full-cell separation (ms)", "with every arm moved (ms)", "grant check, 2 s path (ms)", "samples"
    )
    rows = [bench_collision(n) for n in args.arms]
    for r in rows:
        table.add_row(
            str(r.arms),
            f"{r.separation_ms:.3f}",
            f"{r.place_and_separation_ms:.3f}",
            f"{r.grant_ms:.2f}",
            str(r.grant_samples),
        )
    return print_bench(table, rows, args.json)


def cmd_bench_safety(args: argparse.Namespace) -> int:
    from fleet.bench.safety import bench_safety

    table = Table("arms", "goals", "refused", "check p50 (ms)", "check p99 (ms)", "check / tracker's own plan")
    rows = [bench_safety(n, args.goals) for n in args.arms]
    for r in rows:
        table.add_row(
            str(r.arms),
            str(r.goals),
            str(r.refused),
            f"{r.check_p50_ms:.3f}",
            f"{r.check_p99_ms:.3f}",
            f"{r.check_over_plan:.2f}x",
        )
    return print_bench(table, rows, args.json)


def cmd_bench_snapshot(args: argparse.Namespace) -> int:
    from fleet.bench.snapshots import bench_snapshots

    table = Table(
        "arms",
        "snapshots",
        "line held (ms, median / max)",
        "by stage (ms, the longest)",
        "ticks after, slower by (ms, median / max)",
        "file (kB, max)",
        "write (ms, beside the line)",
        "restore to first tick (s)",
        "restored ends the same",
    )
    rows = []
    for n in args.arms:
        err.print(f"snapshot bench: {n} arms, {args.seconds:g} s, {args.snapshots} snapshots, then a restore")
        rows.append(bench_snapshots(n, args.seconds, args.snapshots))
    for r in rows:
        stages = ", ".join(f"{k} {v:g}" for k, v in r.stall_ms_by_stage.items())
        table.add_row(
            str(r.arms),
            str(r.snapshots),
            f"{r.stall_ms_median:.0f} / {r.stall_ms_max:.0f}",
            stages,
            "-" if r.next_ticks_ms_max is None else f"{r.next_ticks_ms_median:.0f} / {r.next_ticks_ms_max:.0f}",
            f"{r.bytes_max / 1e3:.0f}",
            f"{r.write_ms_max:.0f}",
            f"{r.restore_to_first_tick_s:.2f}",
            "yes" if r.restored_ends_the_same else "NO",
        )
    return print_bench(table, rows, args.json)


def cmd_bench_foxglove(args: argparse.Namespace) -> int:
    from fleet.bench.foxglove import bench_foxglove_cost

    rows = bench_foxglove_cost(args.arms, args.seconds, args.repeats, args.cameras)
    table = Table("variant", "sim loop wall s (median)", "ratio to plain", "frames the client got")
    for r in rows:
        table.add_row(r.variant, f"{r.loop_wall_seconds:.2f}", f"{r.ratio_to_plain:.3f}", f"{r.messages:.0f}")
    return print_bench(table, rows, args.json)


def cmd_bench_ros(args: argparse.Namespace) -> int:
    from fleet.bench.ros import bench_ros_cost, bench_ros_latency

    cost = bench_ros_cost(args.arms, args.seconds, args.subscribers, args.repeats, args.max_rate_hz)
    table = Table("variant", "sim loop wall s (median)", "ratio to plain", "messages per client")
    for r in cost:
        table.add_row(
            r.variant, f"{r.loop_wall_seconds:.2f}", f"{r.ratio_to_plain:.3f}", f"{r.messages_per_client:.0f}"
        )
    latency = bench_ros_latency(args.goals)
    lat = Table("goals", "send -> driving (feedback) p50 / p90 (ms)", "last moving state -> result p50 / p90 (ms)")
    lat.add_row(
        str(latency.goals),
        f"{latency.start_p50_ms:.0f} / {latency.start_p90_ms:.0f}",
        f"{latency.result_after_motion_p50_ms:.0f} / {latency.result_after_motion_p90_ms:.0f}",
    )
    print_bench(table, cost, False)
    return print_bench(lat, [latency], args.json)


def cmd_bench_allocation(args: argparse.Namespace) -> int:
    from fleet.bench.coordinator import bench_allocation

    table = Table("pending tasks", "arms", "optimal assignment (ms)")
    rows = [bench_allocation(n, args.arms) for n in args.tasks]
    for r in rows:
        table.add_row(str(r.tasks), str(r.arms), f"{r.solve_ms:.3f}")
    return print_bench(table, rows, args.json)


def cmd_bench_decisions(args: argparse.Namespace) -> int:
    from fleet.bench.coordinator import bench_decisions

    table = Table("allocator", "arms", "pending hops", "decisions", "p50 (ms)", "p99 (ms)")
    rows = bench_decisions(args.arms, args.pending, args.decisions)
    for r in rows:
        table.add_row(r.allocator, str(r.arms), str(r.pending), str(r.decisions), f"{r.p50_ms:.2f}", f"{r.p99_ms:.2f}")
    return print_bench(table, rows, args.json)


def cmd_bench_lines(args: argparse.Namespace) -> int:
    from fleet.bench.runtime import bench_lines

    cases = [(c.split(":")[0], int(c.split(":")[1]) if ":" in c else None) for c in args.cases]
    table = Table(
        "scene",
        "arms",
        "allocator",
        "throughput (/min)",
        "completed / spawned",
        "bound fraction (of the run's own)",
        "contacts",
        "min separation (m)",
        "grants given / denied",
    )
    rows = bench_lines(cases, args.allocators, args.seconds, args.seed)
    for r in rows:
        sep = "-" if r.min_separation_m is None else f"{r.min_separation_m:.3f}"
        fraction = (
            "-"
            if r.bound_fraction is None
            else f"{r.bound_fraction:.2f} ({'-' if r.run_bound_fraction is None else f'{r.run_bound_fraction:.2f}'})"
        )
        table.add_row(
            r.scene,
            str(r.arms),
            r.allocator,
            f"{r.throughput_per_min:.2f}",
            f"{r.parts_completed} / {r.parts_spawned}",
            fraction,
            str(r.contacts),
            sep,
            f"{r.grants_given} / {r.grants_denied}",
        )
    return print_bench(table, rows, args.json)


def cmd_bench_env(args: argparse.Namespace) -> int:
    from fleet.bench.env import bench_env, bench_robosuite, bench_vector

    if args.vector:
        table = Table(
            "cells", "worker processes", "arms per cell", "scenario", "agent-steps/s", "against 1 cell in process"
        )
        rows = [bench_vector(1, 0, args.arms[0], args.scenarios[0], args.steps)]
        rows += [
            bench_vector(n, min(n, os.cpu_count() or 1), args.arms[0], args.scenarios[0], args.steps)
            for n in args.vector
        ]
        for r in rows:
            table.add_row(
                str(r.cells),
                str(r.cpus),
                str(r.arms),
                r.scenario,
                f"{r.agent_steps_per_s:,.0f}",
                f"{r.agent_steps_per_s / rows[0].agent_steps_per_s:.2f}x",
            )
        return print_bench(table, rows, args.json)

    # before and after: drift hits both
    baseline = [bench_robosuite(args.robosuite, args.steps)] if args.robosuite else []
    rows = [bench_env(n, s, args.steps, distributed=args.distributed) for s in args.scenarios for n in args.arms]
    baseline += [bench_robosuite(args.robosuite, args.steps)] if args.robosuite else []
    robosuite_rate = sum(b.agent_steps_per_s for b in baseline) / len(baseline) if baseline else None
    table = Table(
        "arms",
        "scenario",
        "agent-steps/s",
        "env steps/s",
        "env time / raw physics",
        *(["against robosuite"] if baseline else []),
    )
    for r in rows:
        table.add_row(
            str(r.arms),
            r.scenario,
            f"{r.agent_steps_per_s:,.0f}",
            f"{r.steps / r.env_s:,.0f}",
            f"{r.ratio_to_physics:.2f}",
            *([f"{r.agent_steps_per_s / robosuite_rate:.1f}x"] if baseline else []),
        )
    out.print(table)
    if baseline:
        b = baseline[0]
        out.print(
            f"robosuite {b.robosuite} {b.task} ({b.arms} Pandas, MuJoCo {b.mujoco}): "
            + ", ".join(f"{x.agent_steps_per_s:,.0f}" for x in baseline)
            + " agent-steps/s (before, after)"
        )
    if args.json:
        env_rows = [
            r.__dict__ | {"agent_steps_per_s": r.agent_steps_per_s, "ratio_to_physics": r.ratio_to_physics}
            for r in rows
        ]
        print(json.dumps(env_rows if not baseline else {"env": env_rows, "robosuite": [b.__dict__ for b in baseline]}))
    return 0


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """This group's sub-commands."""
    p = sub.add_parser("bench", help="benchmarks")
    bench = p.add_subparsers(dest="bench", required=True)
    _add_physics(bench)
    _add_bus(bench)
    _add_run(bench)
    _add_monitor(bench)
    _add_record(bench)
    _add_collision(bench)
    _add_safety(bench)
    _add_snapshot(bench)
    _add_ros(bench)
    _add_foxglove(bench)
    _add_allocation(bench)
    _add_lines(bench)
    _add_env(bench)
    bench_cameras.add_parser(bench)
    bench_perception.add_parser(bench)


def _add_physics(bench: argparse._SubParsersAction) -> None:
    b = bench.add_parser("physics", help="raw physics steps/s of the sorting line (no controllers)")
    b.add_argument("--arms", type=int, nargs="+", default=[1, 2, 4, 8])
    b.add_argument("--seconds", type=float, default=4.0, help="sim seconds timed per row")
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench)


def _add_bus(bench: argparse._SubParsersAction) -> None:
    b = bench.add_parser("bus", help="lockstep state-to-command round trip over Zenoh, idle controller processes")
    b.add_argument("--arms", type=int, nargs="+", default=[1, 2, 4, 8])
    b.add_argument("--ticks", type=int, default=1500)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_bus)


def _add_run(bench: argparse._SubParsersAction) -> None:
    b = bench.add_parser("run", help="whole lockstep lines (all processes) against raw physics of the same scene")
    b.add_argument("--arms", type=int, nargs="+", default=[1, 2, 4, 8])
    b.add_argument("--seconds", type=float, default=60.0, help="sim seconds per run")
    b.add_argument("--repeats", type=int, default=3, help="runs per arm count (medians)")
    b.add_argument("--plot", metavar="FILE", help="draw the ratios and the speed against arms to FILE (.png)")
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_run)


def _add_monitor(bench: argparse._SubParsersAction) -> None:
    b = bench.add_parser("monitor", help="lockstep runs without and with the browser monitor: what watching costs")
    b.add_argument("--scene", default="sorting_line")
    b.add_argument("--arms", type=int, default=4)
    b.add_argument("--seconds", type=float, default=30.0, help="sim seconds per run")
    b.add_argument("--repeats", type=int, default=3)
    b.add_argument("--no-browser", action="store_true", help="skip the variant with a headless chromium on the page")
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_monitor)


def _add_record(bench: argparse._SubParsersAction) -> None:
    b = bench.add_parser(
        "record", help="lockstep runs without and with --record: what recording costs, MB per sim minute"
    )
    b.add_argument("--scene", default="assembly_line")
    b.add_argument("--arms", type=int, default=None)
    b.add_argument("--seconds", type=float, default=60.0, help="sim seconds per run")
    b.add_argument("--repeats", type=int, default=3)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_record)


def _add_collision(bench: argparse._SubParsersAction) -> None:
    b = bench.add_parser("collision", help="FCL guard: full-cell separation and one grant check")
    b.add_argument("--arms", type=int, nargs="+", default=[2, 4, 8])
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_collision)


def _add_foxglove(bench: argparse._SubParsersAction) -> None:
    b = bench.add_parser("foxglove", help="what one Foxglove app subscribed to everything costs a lockstep line")
    b.add_argument("--arms", type=int, default=4)
    b.add_argument("--seconds", type=float, default=60.0, help="sim seconds per lockstep run")
    b.add_argument("--repeats", type=int, default=3, help="pairs of runs (plain, served)")
    b.add_argument("--cameras", action="store_true", help="both runs render every camera of the scene")
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_foxglove)


def _add_ros(bench: argparse._SubParsersAction) -> None:
    from fleet.nodes.attached import add_rate_argument

    b = bench.add_parser("ros", help="rosbridge: what N subscribed clients cost a lockstep line; ROS goal latency")
    b.add_argument("--arms", type=int, default=4)
    b.add_argument("--seconds", type=float, default=60.0, help="sim seconds per lockstep run")
    b.add_argument("--subscribers", type=int, default=10, help="clients subscribed to /joint_states and /tf")
    b.add_argument("--repeats", type=int, default=3, help="pairs of runs (plain, served)")
    b.add_argument("--goals", type=int, default=20, help="FollowJointTrajectory goals timed on a realtime line")
    add_rate_argument(b)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_ros)


def _add_safety(bench: argparse._SubParsersAction) -> None:
    b = bench.add_parser("safety", help="the plant's safety layer: its check per trajectory goal")
    b.add_argument("--arms", type=int, nargs="+", default=[2, 4, 8])
    b.add_argument("--goals", type=int, default=400)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_safety)


def _add_snapshot(bench: argparse._SubParsersAction) -> None:
    b = bench.add_parser("snapshot", help="what a snapshot costs a lockstep line, and a restore: the sorting line")
    b.add_argument("--arms", type=int, nargs="+", default=[6])
    b.add_argument("--seconds", type=float, default=30.0, help="sim seconds of the run that takes them")
    b.add_argument("--snapshots", type=int, default=3, help="evenly spaced in the run")
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_snapshot)


def _add_allocation(bench: argparse._SubParsersAction) -> None:
    b = bench.add_parser("allocation", help="optimal assignment for many pending tasks")
    b.add_argument("--tasks", type=int, nargs="+", default=[10, 100, 1000])
    b.add_argument("--arms", type=int, default=8)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_allocation)
    b = bench.add_parser(
        "decisions", help="whole decisions of each built-in allocator (reach, time costs, solve) on a long line"
    )
    b.add_argument("--arms", type=int, default=12)
    b.add_argument("--pending", type=int, default=50, help="belt parts waiting for an arm")
    b.add_argument("--decisions", type=int, default=200)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_decisions)


def _add_lines(bench: argparse._SubParsersAction) -> None:
    b = bench.add_parser("lines", help="throughput, contacts and separation of whole runs per scene and allocator")
    b.add_argument(
        "--cases",
        nargs="+",
        default=[
            "assembly_line",
            "handover",
            "mixed_infeed",
            "pick_cell",
            "sorting_line:2",
            "sorting_line:4",
            "sorting_line:6",
        ],
        help="SCENE or SCENE:ARMS",
    )
    b.add_argument(
        "--allocators", nargs="+", default=["optimal", "auction", "greedy"], choices=("optimal", "auction", "greedy")
    )
    b.add_argument("--seconds", type=float, default=120.0, help="sim seconds per run")
    b.add_argument("--seed", type=seed_number, default=0)
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_lines)


def _add_env(bench: argparse._SubParsersAction) -> None:
    b = bench.add_parser("env", help="PettingZoo env: agent-steps/s and env time against raw physics")
    b.add_argument("--arms", type=int, nargs="+", default=[2, 4, 8])
    b.add_argument("--scenarios", nargs="+", choices=("reach", "pick_place", "line"), default=["reach", "line"])
    b.add_argument("--steps", type=int, default=400)
    b.add_argument("--distributed", action="store_true", help="actions through Zenoh to one process per arm")
    b.add_argument(
        "--vector",
        type=int,
        nargs="+",
        metavar="N",
        help="N cells at once in worker processes (SuperSuit), against one in process",
    )
    b.add_argument(
        "--robosuite",
        metavar="PYTHON",
        help="also time robosuite's TwoArmLift with this interpreter (one that has robosuite; "
        "docs/benchmarks.md says how to make one) before and after, and give each row's agent-steps/s against it",
    )
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench_env)
