"""`fleet twin`: a running line's arms behind the interfaces real arms have (`docs/twin.md`)."""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import math
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from fleet.bus.keys import Keys
from fleet.bus.session import BusEndpoints, add_bus_arguments, open_session
from fleet.cli.bus_flags import check_bus_flags
from fleet.cli.errors import UsageError


def served_calibration(path: Path | None, model: str) -> dict | None:
    """The calibration `--calibration` names: read from the file, or the sim arm's own written there when there is
    none yet (a LeRobot driver then connects without asking); None without the flag (the sim arm's own)."""
    from fleet.twin.calibration import CalibrationError, read_calibration, write_calibration
    from fleet.twin.serve_bus import arm_calibration
    from robots.registry import get_robot

    if path is None:
        return None
    spec = get_robot(model)
    if path.exists():
        try:
            calibration = read_calibration(path, spec)
        except CalibrationError as exc:
            raise UsageError(f"--calibration: {exc}") from None
        print(f"fleet twin: the servos hold the calibration in {path}", flush=True)
        return calibration
    calibration = arm_calibration(spec)
    try:
        write_calibration(path, calibration)
    except OSError as exc:
        raise UsageError(f"--calibration {path}: cannot write it ({exc.strerror})") from None
    print(f"fleet twin: wrote the sim {model}'s calibration to {path}", flush=True)
    return calibration


def need_line_endpoint(args: argparse.Namespace, prog: str) -> None:
    """`--connect` or `--zenoh-config` is given, or `prog` says it needs one."""
    if not (args.connect or args.zenoh_config):
        raise UsageError(f"{prog} needs --connect ENDPOINT (fleet run prints it) or --zenoh-config FILE")


@contextlib.contextmanager
def line_arm_session(args: argparse.Namespace, prog: str) -> Iterator[tuple | None]:
    """The bus session to the line `--connect`/`--zenoh-config` name, its keys and `--arm` of its scene; None where
    no sim answered (said on stderr)."""
    from fleet.nodes.attached import line_scene

    need_line_endpoint(args, prog)
    check_bus_flags(args, wait_s=args.wait)
    keys = Keys(args.run_id)
    with open_session(BusEndpoints.from_args(args)) as session:
        scene = line_scene(session, keys, args.wait, prog)
        if scene is None:
            yield None
            return
        try:
            arm = scene.arm(args.arm)
        except KeyError as exc:
            raise UsageError(f"--arm {args.arm}: {exc.args[0]}") from None
        yield session, keys, arm


def cmd_serve_bus(args: argparse.Namespace) -> int:
    from fleet.common.processes import StopFlag
    from fleet.twin.serve_bus import NoArmState, Wear, served_arm

    for flag, value in (("--backlash-deg", args.backlash_deg), ("--noise-deg", args.noise_deg)):
        if not (math.isfinite(value) and value >= 0.0):
            raise UsageError(f"{flag} {value}: give a finite number of degrees, 0 or more")
    stop = StopFlag(watch_parent=False)
    with line_arm_session(args, "fleet twin serve-bus") as attached:
        if attached is None:
            return 1
        session, keys, served = attached
        calibration = served_calibration(args.calibration, served.model)
        wear = Wear(args.backlash_deg, args.noise_deg, args.seed)
        try:
            with served_arm(session, keys, served, calibration, wear, state_wait_s=args.wait) as (bus, arm):
                print(f"fleet twin: {args.arm}'s servos (ids 1-{len(arm.goals)}) on {bus.port}", flush=True)
                while not stop.should_stop():
                    time.sleep(0.1)
                    for result in arm.refusals():
                        print(f"fleet twin: goal {result.status} by the line: {result.reason}", file=sys.stderr)
        except NoArmState as exc:
            raise UsageError(str(exc)) from None
        print(
            f"fleet twin: {bus.packets} packets answered, {bus.reader.corrupt} with a wrong checksum, "
            f"{arm.sent} goals sent, {len(arm.refused)} refused or aborted by the line",
            file=sys.stderr,
        )
    return 0


def robot_settings(pairs: list[str]) -> dict[str, str]:
    """`--robot KEY=VALUE` flags as LeRobot's `--robot.KEY=VALUE`."""
    settings = {}
    for pair in pairs:
        key, eq, value = pair.partition("=")
        if not eq or not key.strip():
            raise UsageError(f"--robot {pair!r}: give KEY=VALUE, e.g. --robot port=/dev/ttyACM0")
        settings[key.strip()] = value
    return settings


def made_robot(args: argparse.Namespace):
    """The LeRobot robot `--robot-type`/`--robot` name, made (not connected): a wrong type or setting is said before
    anything waits on the line."""
    from fleet.twin.lerobot_robots import RobotTypeError, make_robot

    if importlib.util.find_spec("lerobot") is None:
        raise UsageError(
            "fleet twin mirror drives a LeRobot robot: run it with LeRobot's Python "
            "(bash scripts/install-lerobot; .venv-lerobot/bin/python -m fleet twin mirror ...)"
        )
    try:
        return make_robot(args.robot_type, robot_settings(args.robot))
    except RobotTypeError as exc:
        raise UsageError(str(exc)) from None


def connect(robot, robot_type: str) -> None:
    """Connect `robot` (a calibration prompt would fail: stdin may be closed); a failure said in one line."""
    try:
        robot.connect()
    except Exception as exc:  # LeRobot's drivers raise what their bus raises
        said = " ".join(str(exc).split())  # one line, whatever the driver wrote
        raise UsageError(f"{robot_type} robot: cannot connect ({type(exc).__name__}: {said})") from None


def joint_offsets(pairs: list[str], spec) -> dict[str, float]:
    """`--offset-deg JOINT=DEG` flags: what the robot's degrees read more than each joint's own."""
    offsets = {}
    for pair in pairs:
        joint, eq, value = pair.partition("=")
        if not eq:
            raise UsageError(f"--offset-deg {pair!r}: give JOINT=DEGREES, e.g. --offset-deg shoulder_pan=-3.5")
        if joint not in spec.arm_joints:
            raise UsageError(f"--offset-deg {pair!r}: a {spec.uid}'s arm joints are {', '.join(spec.arm_joints)}")
        try:
            offsets[joint] = float(value)
        except ValueError:
            raise UsageError(f"--offset-deg {pair!r}: {value!r} is not a number of degrees") from None
        if not math.isfinite(offsets[joint]):
            raise UsageError(f"--offset-deg {pair!r}: give a finite number of degrees")
    return offsets


def mirror_until(args: argparse.Namespace, stop) -> Callable[[object], bool]:
    """When the mirror ends: `--duration` sim seconds after its first sample, or Ctrl-C."""
    started: list[float] = []

    def done(sample) -> bool:
        if sample is not None and not started:
            started.append(sample.sim_time_s)
        return stop.should_stop() or (sample is not None and sample.sim_time_s - started[0] >= args.duration)

    return done


def cmd_mirror(args: argparse.Namespace) -> int:
    from fleet.common.processes import StopFlag
    from fleet.twin.line_arm import ArmFeed
    from fleet.twin.mirror import Mirror
    from fleet.twin.mirror_report import mirror_figures, table, write_mirror_files
    from robots.registry import get_robot

    need_line_endpoint(args, "fleet twin mirror")  # said before LeRobot's imports take their seconds
    if not (math.isfinite(args.duration) and args.duration > 0 and math.isfinite(args.rate_hz) and args.rate_hz > 0):
        raise UsageError("--duration and --rate-hz must be positive numbers")
    robot = made_robot(args)
    stop = StopFlag(watch_parent=False)
    with line_arm_session(args, "fleet twin mirror") as attached:
        if attached is None:
            return 1
        session, keys, arm = attached
        spec = get_robot(arm.model)
        offsets = joint_offsets(args.offset_deg, spec)
        connect(robot, args.robot_type)
        feed = ArmFeed(session, keys, args.arm, len(spec.arm_joints) + 1)
        mirror = Mirror(feed, robot, spec, offsets)
        print(f"fleet twin: mirroring {args.arm} onto the {args.robot_type} robot", flush=True)
        try:
            mirror.run(args.rate_hz, mirror_until(args, stop))
        except KeyError as exc:
            raise UsageError(f"the {args.robot_type} robot reads no {exc.args[0]}: not a {spec.uid}") from None
        finally:
            robot.disconnect()
            feed.close()
    if len(mirror.samples) < 2:
        raise UsageError(f"no state of {args.arm} came: is its line running?")
    figures = mirror_figures(mirror.samples, spec.arm_joints)
    print(table(figures), flush=True)
    if args.out is not None:
        written = write_mirror_files(args.out, mirror.samples, spec.arm_joints, figures)
        print(f"wrote {', '.join(p.name for p in written)} in {args.out}", flush=True)
    print(f"fleet twin: {mirror.sent} goals sent to the robot, {mirror.holds} holds", file=sys.stderr)
    return 0


def add_mirror_parser(twin: argparse._SubParsersAction) -> None:
    m = twin.add_parser(
        "mirror",
        help="a LeRobot robot runs an arm's goals beside the line; the deviation per goal and joint (LeRobot's Python)",
    )
    m.add_argument("--arm", required=True, help="the line's arm to mirror (its id in the scene, e.g. arm_1)")
    m.add_argument("--robot-type", required=True, help="LeRobot's robot type, e.g. so101_follower")
    m.add_argument(
        "--robot",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a setting of the robot's config, as LeRobot's --robot.KEY=VALUE (repeatable), e.g. port=/dev/ttyACM0",
    )
    m.add_argument(
        "--offset-deg",
        action="append",
        default=[],
        metavar="JOINT=DEG",
        help="what the robot's degrees read more than the joint's own (repeatable): a calibration whose ranges are "
        "not centred on the URDF's zero; the at-rest figure shows it",
    )
    m.add_argument("--run-id", default="line", help="run id of the line (default line)")
    m.add_argument("--duration", type=float, default=30.0, help="sim seconds to mirror (default 30; Ctrl-C ends too)")
    m.add_argument("--rate-hz", type=float, default=30.0, help="reads and goals a second at most (default 30)")
    m.add_argument("--out", type=Path, help="a folder for deviation.json and samples.csv")
    m.add_argument("--wait", type=float, default=15.0, help="seconds to wait for the line's sim to answer (default 15)")
    add_bus_arguments(m)
    m.set_defaults(func=cmd_mirror)


def add_parsers(sub: argparse._SubParsersAction) -> None:
    """This group's sub-commands."""
    p = sub.add_parser("twin", help="a running line's arms behind a real arm's interfaces (a servo bus)")
    twin = p.add_subparsers(dest="twin", required=True)
    b = twin.add_parser(
        "serve-bus", help="an arm of a running line as STS3215 servos on a pseudo-terminal (LeRobot's SO-101 driver)"
    )
    b.add_argument("--arm", required=True, help="the arm to serve (its id in the scene, e.g. arm_1)")
    b.add_argument("--run-id", default="line", help="run id of the line (default line)")
    b.add_argument(
        "--calibration",
        type=Path,
        help="a LeRobot calibration file (CALIBRATION_DIR/ROBOT_ID.json): the servos hold it; where the file does not "
        "exist yet, the sim arm's own calibration is written there first",
    )
    b.add_argument("--backlash-deg", type=float, default=0.0, help="play in each servo's gears, read back (default 0)")
    b.add_argument(
        "--noise-deg", type=float, default=0.0, help="encoder noise per read, its standard deviation (default 0)"
    )
    b.add_argument("--seed", type=int, default=0, help="seed of the noise (default 0)")
    b.add_argument("--wait", type=float, default=15.0, help="seconds to wait for the line's sim to answer (default 15)")
    add_bus_arguments(b)
    b.set_defaults(func=cmd_serve_bus)
    add_mirror_parser(twin)
