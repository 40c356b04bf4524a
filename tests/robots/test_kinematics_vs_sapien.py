"""Pinocchio's link poses equal SAPIEN's for every registered model (100 random configurations each)."""

import pytest

from fleet.robot_tools.robot_check import kinematics_agree
from robots.registry import get_robot, robot_names

TOL = 1e-5


@pytest.mark.parametrize("uid", robot_names())
def test_link_poses_match_sapien(uid):
    worst_m, worst_rad, missing = kinematics_agree(get_robot(uid), configurations=100)
    assert missing == [], f"{uid}: SAPIEN links without a Pinocchio frame: {missing}"
    assert worst_m < TOL, f"{uid}: position differs by {worst_m:.2e} m"
    assert worst_rad < TOL, f"{uid}: orientation differs by {worst_rad:.2e} rad"
