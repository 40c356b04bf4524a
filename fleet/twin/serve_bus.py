"""`fleet twin serve-bus`: an arm of a running line as the STS3215 servos of its robot on a pseudo-terminal, ids
1.. in joint order, the gripper last (an SO-101's six). A Feetech driver (LeRobot's `SO101Follower` with that
terminal as its `port`, or Feetech's SDK) reads the arm's joints and moves it, as an outside driver of the line."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import zenoh

from fleet.bus.keys import Keys
from fleet.twin.line_arm import LineArm
from fleet.twin.pty_bus import PtyServoBus
from robots.feetech.servos import Servo, ServoLine
from robots.registry import get_robot
from scenes.schema import Arm


@contextlib.contextmanager
def served_arm(session: zenoh.Session, keys: Keys, arm: Arm) -> Iterator[tuple[PtyServoBus, LineArm]]:
    """`arm` of the running line (`Scene.arm(name)`) served as servos on a pseudo-terminal while the block runs."""
    line_arm = LineArm(session, keys, arm.name, get_robot(arm.model))
    servos = ServoLine(Servo(i + 1, joint) for i, joint in enumerate(line_arm.joints()))
    try:
        with PtyServoBus(servos, after_packets=line_arm.send) as bus:
            yield bus, line_arm
    finally:
        line_arm.close()
