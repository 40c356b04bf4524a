"""A policy file as the coordinator's allocator in the real multi-process line (`--allocator policy:FILE`): it runs
with the guard and the real controllers, takes work, and repeats exactly in lockstep."""

import pytest

from tests.coordinator.choice_policies import policy_file
from tests.fleet.test_run import assert_nothing_left, run_lines_together

pytestmark = pytest.mark.slow  # whole runs


def test_a_policy_file_allocates_a_real_line_and_a_lockstep_seed_repeats(tmp_path):
    spec = f"policy:{policy_file(tmp_path, seed=1)}"
    options = {"scene": "mixed_infeed", "duration_s": 40.0, "seed": 2, "allocator": spec}
    (first, launcher), (second, _) = run_lines_together(options, options)
    assert_nothing_left(first, launcher.endpoint)
    assert first["status"] == "ok" and first["allocator"] == "policy:random_1.pt2"
    assert first["parts_completed"] > 0 and first["inter_arm_contacts"] == 0
    assert first["allocator_faults"] == {}
    same = ("parts_completed", "parts_spawned", "parts_missed", "parts_failed", "unfinished_parts")
    assert {k: first[k] for k in same} == {k: second[k] for k in same}
