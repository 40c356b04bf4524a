"""`fleet twin serve-bus`: an arm of a running line as the STS3215 servos of its robot on a pseudo-terminal, ids
1.. in joint order, the gripper last (an SO-101's six). A Feetech driver (LeRobot's `SO101Follower` with that
terminal as its `port`, or Feetech's SDK) reads the arm's joints and moves it, as an outside driver of the line."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import zenoh

from fleet.bus.keys import Keys
from fleet.twin.calibration import MotorCalibration, load_into, sim_calibration
from fleet.twin.line_arm import LineArm
from fleet.twin.pty_bus import PtyServoBus
from robots.feetech.imperfect_joint import ImperfectJoint
from robots.feetech.servos import Servo, ServoJoint, ServoLine
from robots.kinematics import KinematicModel
from robots.registry import get_robot
from robots.spec import RobotSpec
from scenes.schema import Arm


def arm_calibration(spec: RobotSpec) -> dict[str, MotorCalibration]:
    """The sim arm's own servo calibration, from its model's joint limits (`fleet.twin.calibration`)."""
    kinematics = KinematicModel(spec)
    index = [*kinematics.arm_q_index, kinematics.gripper_q_index[0]]
    return sim_calibration(spec, kinematics.lower[index], kinematics.upper[index])


@dataclass(frozen=True)
class Wear:
    """How worn the served servos read: backlash and encoder noise (degrees), drawn from `seed`
    (`robots.feetech.imperfect_joint`)."""

    backlash_deg: float = 0.0
    noise_deg: float = 0.0
    seed: int = 0


@contextlib.contextmanager
def served_arm(
    session: zenoh.Session,
    keys: Keys,
    arm: Arm,
    calibration: dict[str, MotorCalibration] | None = None,
    wear: Wear = Wear(),
    state_wait_s: float = 15.0,
) -> Iterator[tuple[PtyServoBus, LineArm]]:
    """`arm` of the running line (`Scene.arm(name)`) served as servos on a pseudo-terminal while the block runs,
    holding `calibration` (default: the sim arm's own), read as `wear` says; served once its first state came
    (`NoArmState` after `state_wait_s`)."""
    spec = get_robot(arm.model)
    line_arm = LineArm(session, keys, arm.name, spec)
    joints: list[ServoJoint] = list(line_arm.joints())
    if wear.backlash_deg or wear.noise_deg:
        rng = np.random.default_rng(wear.seed)
        joints = [ImperfectJoint(j, wear.backlash_deg, wear.noise_deg, rng) for j in joints]
    servos = ServoLine(Servo(i + 1, joint) for i, joint in enumerate(joints))
    load_into(servos, calibration if calibration is not None else arm_calibration(spec))
    try:
        first_state(line_arm, state_wait_s)
        with PtyServoBus(servos, after_packets=line_arm.send, on_idle=line_arm.renew) as bus:
            yield bus, line_arm
    finally:
        line_arm.close()


class NoArmState(RuntimeError):
    """The served arm's state never came: the line is not running, or has no such arm."""


def first_state(line_arm: LineArm, wait_s: float) -> None:
    """Wait for the arm's first state: a servo reads where its shaft stands, never a made-up zero before it is known
    (`NoArmState` after `wait_s`)."""
    deadline = time.monotonic() + wait_s
    while line_arm.take() is None:
        if time.monotonic() > deadline:
            raise NoArmState(f"no state of {line_arm.arm} within {wait_s:.0f} s: is its line running?")
        time.sleep(0.01)
