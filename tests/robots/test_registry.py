"""The registry: declarations by uid, helpful errors, and the committed OpenClaw URDF is current."""

import pytest

from robots.descriptions.openclaw_build import URDF_PATH, build_urdf
from robots.measured_reach import reach_m_of
from robots.registry import UnknownRobotError, get_robot, robot_names


def test_openclaw_is_always_registered():
    spec = get_robot("openclaw")
    assert spec.arm_dof == 6 and len(spec.gripper_joints) == 2
    assert 0.5 <= reach_m_of(spec) <= 0.56  # measured: 0.51 m straight down at a belt's height, and a margin
    assert {"openclaw", "so101", "panda"} <= set(robot_names())


def test_unknown_robot_lists_the_valid_names():
    with pytest.raises(UnknownRobotError) as info:
        get_robot("ur99")
    message = str(info.value)
    assert "ur99" in message and "openclaw" in message and "panda" in message


def test_committed_urdf_equals_its_generator():
    assert URDF_PATH.read_text() == build_urdf()


def test_gripper_opening_maps_onto_the_finger_joints():
    spec = get_robot("openclaw")
    assert spec.gripper_targets(0.0) == spec.gripper_closed
    assert spec.gripper_targets(1.0) == spec.gripper_open
    assert spec.gripper_targets(2.0) == spec.gripper_open
    width = 0.04
    opening = spec.opening_for_width(width)
    assert abs(sum(spec.gripper_targets(opening)) - width) < 1e-9


def test_a_missing_description_names_the_extra_to_install():
    from robots.registry import MissingModelsError, _example_robot_data

    with pytest.raises(MissingModelsError, match=r"clawfleet\[models\]"):
        _example_robot_data("no_such_description/urdf/none.urdf")
