"""An arm's joints in a LeRobot robot's units, as its SO-101 follower reads a real one: `"<motor>.pos"`, the arm's
joints in degrees (a servo range centred on the joint's zero, as `fleet.twin.calibration` calibrates the sim arm),
the gripper from 0 (closed) to 100 (open), bounded there."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

from fleet.twin.calibration import motor_names
from fleet.twin.line_arm import gripper_opening
from robots.spec import RobotSpec

GRIPPER_SPAN = (0.0, 100.0)  # LeRobot's RANGE_0_100: closed .. open


def positions(spec: RobotSpec, arm_q_rad: Sequence[float], gripper_q_rad: float) -> dict[str, float]:
    """The joints `arm_q_rad` and the gripper at `gripper_q_rad` as LeRobot's `"<motor>.pos"` values."""
    motors = motor_names(spec)
    out = {f"{m}.pos": math.degrees(v) for m, v in zip(motors[:-1], arm_q_rad)}
    out[f"{motors[-1]}.pos"] = GRIPPER_SPAN[1] * gripper_opening(spec, gripper_q_rad)
    return out


def arm_q_rad(spec: RobotSpec, observation: Mapping[str, object]) -> tuple[float, ...]:
    """The arm's joints (rad, in order; not the gripper) from a LeRobot observation (`KeyError` names a missing
    one)."""
    return tuple(math.radians(float(observation[f"{m}.pos"])) for m in motor_names(spec)[:-1])
