"""`fleet robots`, `fleet trials`, `fleet tune`: the robot models, seeded pick trials and drive-gain tuning."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
)
from rich.table import Table

from fleet.cli.errors import (
    UsageError,
    err,
    out,
    seed_number,
)
from robots.measured_reach import reach_m_of
from robots.registry import (
    declared_robots,
    entry_point_problems,
    get_robot,
    is_available,
    register_file,
)
from scenes.loader import first_error


def robot_uid(name_or_file: str) -> str:
    """A registered robot's uid, or the uid of the robot a YAML file declares (registered here)."""
    path = Path(name_or_file)
    if path.suffix in (".yaml", ".yml") or path.exists():
        return register_file(path).uid
    return get_robot(name_or_file).uid


def cmd_robots(args: argparse.Namespace) -> int:
    if args.check:
        return check_robot_lines(robot_uid(args.check), args.trials, args.seed)
    table = Table("robot", "arm DoF", "gripper DoF", "reach (m)", "available", "declared in", "summary")
    for spec in declared_robots():
        uid = spec.uid
        installed = is_available(uid)
        available = "yes" if installed else f"needs the '{spec.needs_extra}' extra"
        table.add_row(
            uid,
            str(spec.arm_dof),
            str(len(spec.gripper_joints)),
            f"{reach_m_of(spec):.2f}" if installed else "-",  # measured from the kinematics: needs the description
            available,
            spec.declared_in,
            spec.summary,
        )
    out.print(table)
    for problem in entry_point_problems():
        err.print(f"problem: {problem}", markup=False, highlight=False)
    return 0


def check_robot_lines(uid: str, trials: int, seed: int) -> int:
    """`fleet robots --check`: one plain line per check; exit 1 when any found a problem."""
    from fleet.robot_tools.robot_check import check_robot

    if trials < 0:
        raise UsageError(f"--trials {trials}: give 0 or more")
    spec = get_robot(uid)
    print(
        f"{uid}: {spec.arm_dof}-DoF arm, {len(spec.gripper_joints)} gripper joint(s), declared in {spec.declared_in}",
        flush=True,
    )
    problems = 0
    for finding in check_robot(spec, trials, seed):
        problems += not finding.ok
        print(finding.line(), flush=True)
    print(f"{uid}: {'no problems found' if problems == 0 else f'{problems} problem(s)'}")
    return 0 if problems == 0 else 1


def cmd_tune(args: argparse.Namespace) -> int:
    """`fleet tune`: a seeded search over a robot's gains and pick timing, each candidate judged by pick trials."""
    from fleet.robot_tools.tuning import candidates, search

    uid = robot_uid(args.robot)
    if args.candidates < 1 or args.trials < 1 or args.jobs < 1:
        raise UsageError("--candidates, --trials and --jobs must be at least 1")
    try:
        count = len(candidates(args.candidates, args.seed, args.vary))  # fewer where the values varied allow fewer
    except ValueError as exc:
        raise UsageError(f"--vary: {exc}") from None
    spec = get_robot(uid)
    with Progress(
        TextColumn(f"{uid} tuning"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(), console=err
    ) as progress:
        bar = progress.add_task("tune", total=count)
        advance = lambda _t: progress.update(bar, advance=1)  # noqa: E731
        results = search(uid, count, args.trials, args.seed, advance, jobs=args.jobs, vary=args.vary)
    names = list(results[0].candidate.describe(spec))
    table = Table(
        "rank",
        "placed",
        "sim s / trial",
        *names,
        title=f"{uid}: {count} settings x {args.trials} trials (seed {args.seed})",
    )
    for rank, tried in enumerate(results, 1):
        values = tried.candidate.describe(spec)
        mark = " (registered)" if tried.candidate == type(tried.candidate)() else ""
        table.add_row(
            f"{rank}{mark}",
            f"{tried.successes}/{tried.trials}",
            f"{tried.mean_sim_s:.2f}",
            *(f"{values[n]:g}" for n in names),
        )
    out.print(table)
    best = results[0]
    for line in best.failures:
        err.print(f"  best setting failed: {line}", markup=False, highlight=False)
    if args.json:
        print(
            json.dumps(
                {
                    "robot": uid,
                    "trials": args.trials,
                    "seed": args.seed,
                    "results": [
                        {"successes": t.successes, "mean_sim_s": t.mean_sim_s, **t.candidate.describe(spec)}
                        for t in results
                    ],
                }
            )
        )
    return 0


def cmd_trials(args: argparse.Namespace) -> int:
    from pydantic import ValidationError

    from fleet.robot_tools.trials import run_trials, trial_scene

    args.robot = robot_uid(args.robot)
    if args.trials < 1:
        raise SystemExit("fleet: error: --trials must be at least 1")
    try:
        scene = trial_scene(args.robot, args.seed, args.physics_hz, args.solver_iterations)
    except ValidationError as exc:
        raise UsageError("{}: {}".format(*first_error(exc, top="scene"))) from None
    failures: list[str] = []
    with Progress(
        TextColumn(f"{args.robot} trials"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[ok]} ok"),
        TimeElapsedColumn(),
        console=err,
        transient=False,
    ) as progress:
        bar = progress.add_task("trials", total=args.trials, ok=0)
        ok = 0

        def on_result(result) -> None:
            nonlocal ok
            ok += result.success
            if not result.success:
                failures.append(f"seed {result.seed}: {result.phase}: {result.reason}")
            progress.update(bar, advance=1, ok=ok)

        results = run_trials(args.robot, args.trials, args.seed, on_result, args.physics_hz, args.solver_iterations)
    successes = sum(r.success for r in results)
    summary = {
        "robot": args.robot,
        "trials": len(results),
        "successes": successes,
        "success_rate": successes / len(results),
        "physics_hz": scene.physics_hz,
        "solver_iterations": scene.solver_position_iterations,
    }
    for line in failures:
        err.print(f"  failed: {line}")
    out.print(f"{args.robot}: {successes}/{len(results)} picks placed, success rate {summary['success_rate']:.2f}")
    if args.json:
        print(json.dumps(summary))
    return 0


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """This group's sub-commands."""
    p = sub.add_parser("robots", help="list the registered robot models, or check one (--check)")
    p.add_argument(
        "--check",
        metavar="ROBOT",
        default=None,
        help="a robot uid or robot YAML file: kinematics against the physics, home, gripper, pick trials",
    )
    p.add_argument("--trials", type=int, default=3, help="pick trials with --check (0: none)")
    p.add_argument("--seed", type=seed_number, default=0, help="first trial seed with --check")
    p.set_defaults(func=cmd_robots)

    p = sub.add_parser("trials", help="seeded pick-and-place trials: conveyor to bin, friction grasps")
    p.add_argument("--robot", default="openclaw", help="a robot uid or robot YAML file")
    p.add_argument("--trials", type=int, default=50)
    p.add_argument("--seed", type=seed_number, default=0)
    p.add_argument(
        "--physics-hz", type=float, default=None, help="physics rate to try (a whole multiple of the 100 Hz servo rate)"
    )
    p.add_argument(
        "--solver-iterations", type=int, default=None, help="PhysX position iterations to try (the scene's: 20)"
    )
    p.add_argument("--json", action="store_true", help="last stdout line: one JSON object")
    p.set_defaults(func=cmd_trials)

    p = sub.add_parser("tune", help="seeded search over a robot's drive gains and pick timing, judged by pick trials")
    p.add_argument("--robot", default="openclaw", help="a robot uid or robot YAML file")
    p.add_argument(
        "--candidates", type=int, default=12, help="settings tried: the registered one and draws from the search space"
    )
    p.add_argument("--trials", type=int, default=20, help="seeded pick trials per setting")
    p.add_argument("--seed", type=seed_number, default=0, help="seed of the draws and first trial seed")
    p.add_argument(
        "--jobs", type=int, default=1, help="settings tried at once, each in a process of its own (same results)"
    )
    p.add_argument(
        "--vary",
        nargs="+",
        metavar="VALUE",
        help="search only these values, the others as registered (a wrong name lists the valid ones; default: all)",
    )
    p.add_argument("--json", action="store_true", help="last stdout line: one JSON object")
    p.set_defaults(func=cmd_tune)
