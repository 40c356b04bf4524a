"""A served arm's calibration in LeRobot's file format: the sim SO-101's own (each joint's degrees its own angle),
written and read back, loaded into its servos; a file that cannot be served is refused naming the file and field."""

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.twin.calibration import (
    CalibrationError,
    load_into,
    motor_names,
    read_calibration,
    write_calibration,
)
from fleet.twin.line_arm import ticks_of
from fleet.twin.serve_bus import arm_calibration
from robots.feetech.control_table import BY_NAME
from robots.feetech.servos import Servo, ServoLine
from robots.registry import get_robot
from tests.robots.feetech.joints import StiffJoint

SO101 = get_robot("so101")


def lerobot_degrees(ticks: int, range_min: int, range_max: int) -> float:
    """LeRobot's `MotorNormMode.DEGREES` reading of a servo (`FeetechMotorsBus._normalize`)."""
    return (ticks - (range_min + range_max) / 2) * 360 / 4095


def test_the_sim_so101s_calibration_reads_each_joint_in_its_own_degrees():
    calibration = arm_calibration(SO101)
    assert list(calibration) == list(motor_names(SO101)) == [*SO101.arm_joints, "gripper"]
    assert [c.id for c in calibration.values()] == [1, 2, 3, 4, 5, 6]
    for joint in SO101.arm_joints:
        c = calibration[joint]
        assert c.homing_offset == 0 and (c.range_min + c.range_max) / 2 == 2048
        for q_deg in (-60.0, 0.0, 45.0):
            assert lerobot_degrees(ticks_of(np.radians(q_deg)), c.range_min, c.range_max) == pytest.approx(
                q_deg, abs=0.1
            )
    gripper = calibration["gripper"]  # 0 closed, 100 open
    assert (gripper.range_min, gripper.range_max) == (
        ticks_of(SO101.gripper_closed[0]),
        ticks_of(SO101.gripper_open[0]),
    )


def test_a_calibration_written_reads_back_and_its_servos_hold_it(tmp_path):
    path = tmp_path / "cal" / "arm_1.json"
    calibration = arm_calibration(SO101)
    write_calibration(path, calibration)
    assert read_calibration(path, SO101) == calibration
    shafts = [StiffJoint(2048 + 100) for _ in range(6)]
    line = ServoLine(Servo(i + 1, shaft) for i, shaft in enumerate(shafts))
    real = calibration | {"shoulder_pan": calibration["shoulder_pan"].model_copy(update={"homing_offset": -30})}
    load_into(line, real)
    pan = line.servos[1]
    assert pan.get(BY_NAME["Min_Position_Limit"]) == real["shoulder_pan"].range_min
    assert pan.get(BY_NAME["Homing_Offset"]) == -30
    present = int.from_bytes(pan.read(BY_NAME["Present_Position"].address, 2), "little")
    assert present == 2148 + 30  # the shaft less the homing offset


@pytest.mark.parametrize(
    ("content", "says"),
    [
        ("not json", "not a calibration file"),
        ("[1, 2]", "one object per motor"),
        ('{"shoulder_pan": {"id": 1}}', "shoulder_pan.homing_offset: Field required"),
        ('{"shoulder_pan": {"id": 1, "homing_offset": 0, "range_min": 0, "range_max": 9000}}', "range_max"),
        ('{"shoulder_pan": {"id": 1, "homing_offset": 0, "range_min": 0, "range_max": 10, "speed": 1}}', "speed"),
        ('{"pan\\nlift": {"id": 1}}', r"pan\\nlift\.homing_offset"),  # a newline in a name, escaped
    ],
)
def test_a_file_that_is_not_a_calibration_is_refused_naming_the_file_and_field(tmp_path, content, says):
    path = tmp_path / "arm_1.json"
    path.write_text(content)
    with pytest.raises(CalibrationError, match=says) as refused:
        read_calibration(path, SO101)
    assert str(refused.value).startswith(f"{path}: ") and "\n" not in str(refused.value)


def test_a_calibration_of_another_robot_is_refused(tmp_path):
    path = tmp_path / "arm_1.json"
    entries = {n: c.model_dump() for n, c in arm_calibration(SO101).items()}
    for broken, says in (
        ({k: v for k, v in entries.items() if k != "gripper"}, "no motor 'gripper'"),
        (entries | {"elbow_flex": entries["elbow_flex"] | {"id": 7}}, "elbow_flex.id: 7, but elbow_flex is servo 3"),
        (entries | {"extra": entries["gripper"] | {"id": 7}}, "motor 'extra' is not one of a so101's"),
        (entries | {"gripper": entries["gripper"] | {"range_min": 3000}}, "gripper.range_min: not below range_max"),
    ):
        path.write_text(json.dumps(broken))
        with pytest.raises(CalibrationError, match=says):
            read_calibration(path, SO101)


JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-5000, 5000) | st.floats(allow_nan=False) | st.text(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=12), inner, max_size=7),
    max_leaves=30,
)


@settings(max_examples=200, deadline=None)
@given(
    st.dictionaries(
        st.sampled_from([*motor_names(SO101), "x"]),
        st.fixed_dictionaries(
            {},
            optional={
                k: st.integers(-5000, 5000) | JSON
                for k in ("id", "drive_mode", "homing_offset", "range_min", "range_max", "other")
            },
        )
        | JSON,
    )
    | JSON
)
def test_any_json_is_a_calibration_or_refused_with_one_line(tmp_path_factory, content):
    path = tmp_path_factory.mktemp("cal") / "arm_1.json"
    path.write_text(json.dumps(content))
    try:
        calibration = read_calibration(path, SO101)
    except CalibrationError as refused:
        assert str(refused).startswith(f"{path}: ") and "\n" not in str(refused)
    else:
        assert list(calibration) == list(motor_names(SO101)) or set(calibration) == set(motor_names(SO101))
