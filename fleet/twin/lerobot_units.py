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


def positions(
    spec: RobotSpec, arm_q_rad: Sequence[float], gripper_q_rad: float, offsets_deg: Mapping[str, float] | None = None
) -> dict[str, float]:
    """The joints `arm_q_rad` and the gripper at `gripper_q_rad` as LeRobot's `"<motor>.pos"` values; `offsets_deg`
    (by joint): what a robot's degrees read more than the joint's own (a calibration whose range is not centred on
    the URDF's zero)."""
    motors, offsets = motor_names(spec), offsets_deg or {}
    out = {f"{m}.pos": math.degrees(v) + offsets.get(m, 0.0) for m, v in zip(motors[:-1], arm_q_rad)}
    out[f"{motors[-1]}.pos"] = GRIPPER_SPAN[1] * gripper_opening(spec, gripper_q_rad)
    return out


def arm_q_rad(
    spec: RobotSpec, observation: Mapping[str, object], offsets_deg: Mapping[str, float] | None = None
) -> tuple[float, ...]:
    """The arm's joints (rad, in order; not the gripper) from a LeRobot observation, less `offsets_deg` (`KeyError`
    names a missing one)."""
    offsets = offsets_deg or {}
    return tuple(math.radians(float(observation[f"{m}.pos"]) - offsets.get(m, 0.0)) for m in motor_names(spec)[:-1])
