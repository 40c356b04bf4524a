"""The main job's line with and without pipelined fixtures, as real processes: with it, arms are held at the
fixture's edge (and say so in the summary) and the line finishes more; without it, nobody is held."""

from fleet.launcher import Launcher, RunOptions
from tests.fleet.test_run import assert_nothing_left


def run(pipeline: bool) -> dict:
    with Launcher(RunOptions(scene="assembly_line", duration_s=60.0, pipeline=pipeline)) as launcher:
        summary = launcher.run()
    assert_nothing_left(summary, launcher.endpoint)
    assert summary["status"] == "ok" and summary["inter_arm_contacts"] == 0, summary
    return summary


def test_pipelined_fixtures_hold_arms_at_the_edge_and_finish_more_than_arms_taking_turns():
    pipelined, in_turns = run(True), run(False)
    assert pipelined["pipeline"] is True and in_turns["pipeline"] is False
    held = {a: t["held_at_fixture"] for a, t in pipelined["arm_time"].items()}
    assert held["arm_1"] > 0 and held["arm_2"] > 0, held  # the top waited for its base, the ship for its top
    assert all(t["held_at_fixture"] == 0 for t in in_turns["arm_time"].values())
    assert pipelined["held_at_station_s"] and not in_turns["held_at_station_s"]
    assert pipelined["parts_completed"] > in_turns["parts_completed"], (pipelined["parts_completed"], in_turns["parts_completed"])
