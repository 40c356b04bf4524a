"""A served arm's servo calibration, in LeRobot's file format (`<robot id>.json`: per motor, its id, drive mode,
homing offset and range in ticks). A LeRobot driver connects without asking anything only when the servos hold
the calibration its file names, so `fleet twin serve-bus --calibration FILE` loads a file into the servos, or,
where none exists yet, writes the sim arm's own there (derived from its joint limits) for the driver to use."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from fleet.twin.line_arm import TICKS_PER_RAD, ZERO_TICKS, ticks_of
from robots.feetech.control_table import BY_NAME, TICKS_PER_TURN
from robots.feetech.servos import ServoLine
from robots.spec import RobotSpec
from scenes.yaml_file import one_line


class MotorCalibration(BaseModel):
    """One motor's entry in a LeRobot calibration file (`lerobot.motors.MotorCalibration`, ticks)."""

    model_config = ConfigDict(extra="forbid", frozen=True)
    id: int = Field(ge=0, le=253)
    drive_mode: int = Field(default=0, ge=0, le=0)  # Feetech servos have none: LeRobot writes 0
    homing_offset: int = Field(ge=-2047, le=2047)  # sign and magnitude in 11 bits
    range_min: int = Field(ge=0, le=TICKS_PER_TURN - 1)
    range_max: int = Field(ge=0, le=TICKS_PER_TURN - 1)


class CalibrationError(ValueError):
    """A calibration file that cannot be served: the message names the file and the field, on one line."""

    def __init__(self, message: str) -> None:
        super().__init__(one_line(message))


def motor_names(spec: RobotSpec) -> tuple[str, ...]:
    """The served motors' names, in servo id order (1..): the arm's joints, then the gripper (an SO-101's are
    LeRobot's own names)."""
    return (*spec.arm_joints, spec.gripper_joints[0])


def sim_calibration(spec: RobotSpec, lower_rad: np.ndarray, upper_rad: np.ndarray) -> dict[str, MotorCalibration]:
    """The sim arm's calibration: no homing offset; an arm joint's range centred on its zero (tick 2048, so that
    LeRobot's degrees are the joint's own) and wide enough for its limits (`lower_rad`/`upper_rad`, in
    `motor_names` order) or the whole turn, as LeRobot leaves a wrist roll; the gripper's from closed (0) to open
    (100)."""
    names = motor_names(spec)
    calibration = {}
    for i, name in enumerate(names[:-1]):
        half = min(ZERO_TICKS - 1, math.ceil(max(abs(lower_rad[i]), abs(upper_rad[i])) * TICKS_PER_RAD))
        calibration[name] = MotorCalibration(
            id=i + 1, homing_offset=0, range_min=ZERO_TICKS - half, range_max=ZERO_TICKS + half
        )
    closed, opened = ticks_of(spec.gripper_closed[0]), ticks_of(spec.gripper_open[0])
    calibration[names[-1]] = MotorCalibration(
        id=len(names), homing_offset=0, range_min=min(closed, opened), range_max=max(closed, opened)
    )
    return calibration


def read_calibration(path: Path, spec: RobotSpec) -> dict[str, MotorCalibration]:
    """The calibration in `path`, checked against the served motors (every one, with its servo id)."""
    try:
        raw = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CalibrationError(f"{path}: not a calibration file ({exc})") from None
    if not isinstance(raw, dict):
        raise CalibrationError(f"{path}: a calibration file holds one object per motor, by name")
    calibration = {}
    for name, entry in raw.items():
        try:
            calibration[name] = MotorCalibration.model_validate(entry)
        except ValidationError as exc:
            error = exc.errors()[0]
            where = ".".join(str(p) for p in (name, *error["loc"]))
            raise CalibrationError(f"{path}: {where}: {error['msg']}") from None
    for servo_id, name in enumerate(motor_names(spec), start=1):
        if name not in calibration:
            raise CalibrationError(f"{path}: no motor {name!r} (a {spec.uid} has {', '.join(motor_names(spec))})")
        if calibration[name].id != servo_id:
            raise CalibrationError(f"{path}: {name}.id: {calibration[name].id}, but {name} is servo {servo_id}")
    if extra := sorted(set(calibration) - set(motor_names(spec))):
        raise CalibrationError(f"{path}: motor {extra[0]!r} is not one of a {spec.uid}'s")
    if bad := [n for n, c in calibration.items() if c.range_min >= c.range_max]:
        raise CalibrationError(f"{path}: {bad[0]}.range_min: not below range_max")
    return calibration


def write_calibration(path: Path, calibration: dict[str, MotorCalibration]) -> None:
    """`calibration` as LeRobot writes its files (indented JSON, motors in servo order)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({n: c.model_dump() for n, c in calibration.items()}, indent=4) + "\n")


def load_into(line: ServoLine, calibration: dict[str, MotorCalibration]) -> None:
    """Each motor's homing offset and position limits into its servo's memory, as LeRobot's `write_calibration`
    puts them there."""
    for entry in calibration.values():
        servo = line.servos[entry.id]
        servo.set(BY_NAME["Homing_Offset"], entry.homing_offset)
        servo.set(BY_NAME["Min_Position_Limit"], entry.range_min)
        servo.set(BY_NAME["Max_Position_Limit"], entry.range_max)
