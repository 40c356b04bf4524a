"""A fixture line of several bays (`fleet run assembly_line --arms 6`): each bay's bases ride in from its own
infeed down one belt, and each bay assembles and ships at its own fixture, with zero contacts between bays."""

import pytest

from fleet.run.launcher import Launcher, RunOptions
from tests.fleet.test_run import assert_nothing_left

pytestmark = pytest.mark.slow


def test_two_bays_down_one_belt_each_assemble_their_own_parts_with_zero_contacts():
    with Launcher(RunOptions(scene="assembly_line", arms=6, duration_s=45.0)) as launcher:
        summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert summary["status"] == "ok" and summary["inter_arm_contacts"] == 0, summary.get("error")
    assert summary["arm_ids"] == [f"arm_{i}" for i in range(6)]
    assert summary["parts_missed"] == 0 and summary["parts_failed"] == 0
    assert summary["parts_completed"] >= 6, summary["parts_completed"]
    # the arm that ships finished assemblies works in both bays: each fixture completed its own
    assert summary["arm_time"]["arm_2"]["working"] > 0.05 and summary["arm_time"]["arm_5"]["working"] > 0.05
    assert summary["throughput_bound_per_min"] == 12.0  # two bays of 6 parts a minute
